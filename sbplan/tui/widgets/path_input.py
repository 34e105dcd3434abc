"""A path input that completes file and folder names as the operator types."""

from __future__ import annotations

import os
from pathlib import Path

from textual.suggester import Suggester
from textual.widgets import Input


class PathSuggester(Suggester):
    """Suggests the first file or folder (sorted) whose name starts with what was typed.

    Folders get a trailing ``/`` so the next part can be completed right away. Hidden entries are
    offered only once a ``.`` is typed.
    """

    def __init__(self, suffixes: tuple[str, ...] = ()) -> None:
        super().__init__(use_cache=False, case_sensitive=True)
        self.suffixes = tuple(s.lower() for s in suffixes)

    async def get_suggestion(self, value: str) -> str | None:
        if not value:
            return None
        folder, prefix = os.path.split(os.path.expanduser(value))
        base = Path(folder or ".")
        try:
            entries = sorted(os.scandir(base), key=lambda e: e.name)
        except OSError:
            return None
        for e in entries:
            if not e.name.startswith(prefix):
                continue
            if e.name.startswith(".") and not prefix.startswith("."):
                continue
            is_dir = e.is_dir()
            if not is_dir and self.suffixes and not e.name.lower().endswith(self.suffixes):
                continue
            head = value[: len(value) - len(prefix)]
            candidate = head + e.name + (os.sep if is_dir else "")
            if candidate != value:
                return candidate
        return None


class PathInput(Input):
    """An :class:`Input` for paths, with completion (accept with → or End)."""

    def __init__(self, value: str = "", *, suffixes: tuple[str, ...] = (), **kwargs) -> None:
        kwargs.setdefault("compact", True)  # one row: the side panel must fit under the picture at 80 x 24
        super().__init__(value=value, suggester=PathSuggester(suffixes), **kwargs)
