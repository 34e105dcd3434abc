"""The footer of key bindings, in two rows when one row would cut keys off."""

from __future__ import annotations

from itertools import groupby

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import HorizontalGroup
from textual.widgets import Footer
from textual.widgets._footer import FooterKey, FooterLabel, KeyGroup

#: Columns the command palette's key takes at the right of the footer.
_PALETTE_WIDTH = 12


class KeyFooter(Footer):
    """Textual's compact footer, whose keys go on two rows when one row cannot hold them (80
    columns), so that every key of every screen is seen.

    Composed as :class:`~textual.widgets.Footer` composes (bindings shown, one entry per action,
    a group's keys together with the group's description), in rows.
    """

    def __init__(self, **kwargs) -> None:
        kwargs.setdefault("compact", True)
        super().__init__(**kwargs)
        self._two_rows = False
        self._total = 0  # columns the keys need in one row

    def _units(self) -> list[tuple[list, Binding.Group | None, int]]:
        """``(bindings, Binding.Group or None, columns)`` per footer entry, in order."""
        by_action: dict[str, list] = {}
        for _, binding, enabled, tooltip in self.screen.active_bindings.values():
            if binding.show:
                by_action.setdefault(binding.action, []).append((binding, enabled, tooltip))
        units: list[tuple[list, Binding.Group | None, int]] = []
        for group, grouped in groupby(by_action.values(), lambda m: m[0][0].group):
            members = list(grouped)
            if group is not None and len(members) > 1:
                keys = [m[0] for m in members]
                width = sum(len(self.app.get_key_display(b)) + 1 for b, _, _ in keys) + len(group.description) + 3
                units.append((keys, group, width))
            else:
                for m in members:
                    b = m[0][0]
                    units.append(([m[0]], None, len(self.app.get_key_display(b)) + len(b.description) + 1))
        return units

    def compose(self) -> ComposeResult:
        if not self._bindings_ready:
            return
        units = self._units()
        palette = self.show_command_palette and self.app.ENABLE_COMMAND_PALETTE \
            and self.app.COMMAND_PALETTE_BINDING in self.screen.active_bindings
        # entries stand one column apart
        self._total = sum(w for *_, w in units) + max(len(units) - 1, 0) + (_PALETTE_WIDTH if palette else 0)
        self._two_rows = self._total > self.app.size.width
        self.set_class(self._two_rows, "-two-rows")
        rows = [units]
        if self._two_rows:
            # the first row takes entries while they fit, the second the rest
            room, n, used = self.app.size.width - (_PALETTE_WIDTH if palette else 0), 0, 0
            while n < len(units) - 1 and used + (n > 0) + units[n][2] <= room:
                used += (n > 0) + units[n][2]
                n += 1
            rows = [units[:n], units[n:]]
        for row in rows:
            with HorizontalGroup(classes="key-row"):
                for keys, group, _ in row:
                    if group is not None:
                        with KeyGroup(classes="-compact" if group.compact else ""):
                            for binding, enabled, tooltip in keys:
                                yield FooterKey(binding.key, self.app.get_key_display(binding), "", binding.action,
                                                disabled=not enabled, tooltip=tooltip or binding.description,
                                                classes="-grouped").data_bind(compact=Footer.compact)
                        yield FooterLabel(group.description)
                    else:
                        binding, enabled, tooltip = keys[0]
                        yield FooterKey(binding.key, self.app.get_key_display(binding), binding.description,
                                        binding.action, disabled=not enabled,
                                        tooltip=tooltip).data_bind(compact=Footer.compact)
        if palette:
            _, binding, enabled, tooltip = self.screen.active_bindings[self.app.COMMAND_PALETTE_BINDING]
            yield FooterKey(binding.key, self.app.get_key_display(binding), binding.description, binding.action,
                            classes="-command-palette", disabled=not enabled,
                            tooltip=binding.tooltip or binding.description)

    def on_resize(self) -> None:
        if self._total and self._two_rows != (self._total > self.app.size.width):
            self.refresh(recompose=True)
