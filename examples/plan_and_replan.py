"""Plan a route around the obstacles on a floor, then replan when a new obstacle appears.

Run it from the repository root (it takes a few seconds):

    python examples/plan_and_replan.py

The floor is maps/paper-8x6, the paper's worked example: 8 x 6 printed symbols, three obstacles.
Coordinates are metres in the world frame of the map's workspace.toml: x to the right, y up.
"""

import numpy as np
from shapely.geometry import box

import sbplan
from sbplan.planning import detection_obstacles

MAP = "maps/paper-8x6"


def show(what, route):
    print(f"{what}: {route.status} route by {route.planner}, {route.length:.3f} m, replanned={route.replanned}")
    print("   " + " -> ".join(f"({x:.2f}, {y:.2f})" for x, y in route.waypoints))


# 1. Where are the obstacles? Calibrate on the image of the empty floor (the symbol grid, and the
#    world frame from the map's workspace.toml), then detect the obstacles on a scene.
calibration = sbplan.calibrate(f"{MAP}/reference.png", workspace=MAP)
detection = sbplan.detect(f"{MAP}/scene-01.png", calibration)
obstacles = detection_obstacles(detection)  # under the default obstacle model (parts), in metres
print(f"{len(obstacles.polygons)} obstacles; workspace (xmin, ymin, xmax, ymax) = "
      f"({', '.join(f'{v:.2f}' for v in obstacles.bounds)})")

# 2. Plan the shortest route for a disc robot from the map's start to its goal. Obstacles are
#    enlarged by the robot's radius; the route bends only at the corners of the enlarged ones.
ws = calibration.workspace
route = sbplan.plan(obstacles.polygons, ws.start_m, ws.goal_m, robot_radius=ws.robot_radius_m,
                    bounds=obstacles.bounds)
show("planned", route)

# 3. The robot has reached the route's first corner when a box (30 cm square) drops onto the
#    middle of the next leg but one. replan plans from the robot's position, around the old and
#    the new obstacles, to the same goal (with the planner that made the route).
robot = route.waypoints[1]
x, y = (route.waypoints[2] + route.waypoints[3]) / 2
new_box = box(x - 0.15, y - 0.15, x + 0.15, y + 0.15)
detour = sbplan.replan(route, robot, [new_box])
show("after a box fell on the route", detour)
rest = route.length - float(np.hypot(*(route.waypoints[1] - route.waypoints[0])))
print(f"   (the old route from the robot on: {rest:.3f} m)")

# 4. An obstacle that does not touch the rest of the route changes nothing: replan returns the
#    remaining route as it is (replanned=False).
behind = box(0.0, 2.6, 0.3, 2.9)  # in a corner of the floor, away from the route
show("after a box fell elsewhere", sbplan.replan(detour, robot, [behind]))
