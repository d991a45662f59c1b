"""Progress of the long commands' stages (design: scan, search, FE verification,
refinement; sweeps; charts) through tqdm: one bar per stage on stderr, off when stderr is
not a terminal or under CI (``CI`` set), or when asked (``--no-progress``)."""

from __future__ import annotations

import os
import sys


def enabled(asked: bool = True) -> bool:
    """Bars only for a person at a terminal."""
    return bool(asked and sys.stderr.isatty() and not os.environ.get("CI"))


class Stage:
    """A stage's bar (``total`` None: a counter) and its count of finished items; usable as
    a context manager. ``done`` counts whether the bar shows or not (the final message says
    what each stage ran)."""

    def __init__(self, name: str, total: int | None = None, show: bool = True,
                 unit: str = "run"):
        self.name, self.done, self.bar = name, 0, None
        if show:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=name, unit=unit, file=sys.stderr, leave=True,
                            dynamic_ncols=True)

    def update(self, n: int = 1, note: str = ""):
        self.done += n
        if self.bar is not None:
            if note:
                self.bar.set_postfix_str(note, refresh=False)
            self.bar.update(n)

    def grow(self, n: int):
        """More items than planned (a refinement, a bisection step)."""
        if self.bar is not None and self.bar.total is not None:
            self.bar.total += n
            self.bar.refresh()

    def close(self):
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
