"""Tables whose columns are sized when they are filled."""

from __future__ import annotations

from typing import Iterable, Sequence

from rich.cells import cell_len
from textual.widgets import DataTable


def fill_table(table: DataTable, labels: Sequence[str], rows: Iterable[Sequence[str]], *,
               keys: Sequence[str] | None = None) -> None:
    """Replace ``table``'s columns and rows: each column as wide as its widest cell or its label.

    A DataTable sizes columns of automatic width only when it next goes idle. A repaint before
    that (on a busy machine) caches the header at the old widths, and it stays so: the widths
    change without the table's line cache noticing. Widths given here hold from the first paint.

    Parameters
    ----------
    table : DataTable
    labels : sequence of str
        The column labels.
    rows : iterable of sequences of str
        The cells, one sequence per row, in the order of ``labels``.
    keys : sequence of str, optional
        A key per row.
    """
    cells = [list(row) for row in rows]
    if any(len(row) != len(labels) for row in cells):
        raise ValueError(f"rows: expected {len(labels)} cells in each row")
    if keys is not None and len(keys) != len(cells):
        raise ValueError(f"keys: expected one per row ({len(cells)}), got {len(keys)}")
    table.clear(columns=True)
    for i, label in enumerate(labels):
        table.add_column(label, width=max([cell_len(label), *(cell_len(row[i]) for row in cells)]))
    for i, row in enumerate(cells):
        table.add_row(*row, key=None if keys is None else keys[i])
