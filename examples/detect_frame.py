"""Find the obstacles on a frame of the ceiling camera, and notice when the camera has moved.

Run it from the repository root (it takes a few seconds):

    python examples/detect_frame.py

The floor is maps/paper-8x6, the paper's worked example: 8 x 6 printed symbols, three obstacles.
Cells are (row, col), row 0 at the top of the image; pixels are (x, y), y down; metres are the
world frame of the map's workspace.toml: x to the right, y up.
"""

import cv2
import numpy as np

import sbplan
from sbplan.detection import Detector
from sbplan.imageio import load_image

MAP = "maps/paper-8x6"

# 1. Calibrate once, on an image of the empty floor: this finds the symbol grid and how much two
#    outlines may differ and still be "the same symbol". workspace= adds the world frame (metres).
calibration = sbplan.calibrate(f"{MAP}/reference.png", workspace=MAP)
grid = calibration.grid
print(f"calibrated: {grid.rows} rows x {grid.cols} columns of symbols")

# 2. Detect a frame. A cell is occupied when its symbol is missing or does not look like the
#    reference symbol any more; neighbouring occupied cells form one obstacle.
#    One Detector per camera stream: it keeps the camera's last pose for the next frame.
detector = Detector(calibration)
frame = load_image(f"{MAP}/scene-01.png")  # (H, W) grey levels, uint8
detection = detector(frame)
print(f"{detection.symbols_found} of {detection.symbols_expected} symbols seen; "
      f"occupied cells (row, col): {detection.occupied_cells}")

# 3. Each obstacle: its cells, and its minimum-area rectangle in metres (4 corners (x, y)).
for obstacle in detection.obstacles:
    corners = " ".join(f"({x:.2f}, {y:.2f})" for x, y in obstacle.mar_m)
    print(f"obstacle {obstacle.id}: {len(obstacle.cells)} cells, corners in metres {corners}")

# 4. Every frame is registered against the calibration first, so a camera that was bumped does
#    not make the whole floor look occupied. The frame above was taken from where the camera
#    was at calibration:
print(detection.camera.summary())

# Now move the view as a bumped camera would: 6 px right, 4 px up, 0.5 degree. The cells found
# stay the same, and the movement is measured (in the calibration's pixels).
bump = cv2.getRotationMatrix2D((frame.shape[1] / 2, frame.shape[0] / 2), 0.5, 1.0)
bump[:, 2] += (6.0, -4.0)
moved = cv2.warpAffine(frame, bump, (frame.shape[1], frame.shape[0]), borderMode=cv2.BORDER_REPLICATE)
after = detector(moved)
same = np.array_equal(after.occupied, detection.occupied)
print(f"after the bump: {after.camera.summary()}")
print(f"   same occupied cells as before: {same}")
