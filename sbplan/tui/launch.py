"""Starting the app from the command line (the CLI stays free of Textual imports)."""

from __future__ import annotations


def launch(map_dir: str | None, *, auto: bool = True, images: str = "auto") -> None:
    """Run :class:`~sbplan.tui.app.SbplanApp` in this terminal until the operator quits.

    ``images`` is ``"auto"`` (the terminal's graphics when detected), ``"halfcell"`` or ``"unicode"``.
    """
    # textual-image asks the terminal what it can draw; that must happen before Textual takes it over
    import textual_image.widget as tiw

    image_class = {"auto": tiw.Image, "halfcell": tiw.HalfcellImage, "unicode": tiw.UnicodeImage}[images]
    # (Textual itself, after textual-image; and sbplan.commands.tui imports this module only to run the app)
    from .app import SbplanApp

    SbplanApp(map_dir, auto=auto, image_class=image_class).run()
