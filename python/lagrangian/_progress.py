"""The progress bar of long integrations: ``tqdm.auto`` when installed (a widget in Jupyter,
text on a terminal), otherwise one line on stderr redrawn in place. The native module creates
it after a run has taken a second and feeds it the fraction done."""

from __future__ import annotations

import sys


class Bar:
    def __init__(self, label: str) -> None:
        self._last = -1
        try:
            from tqdm.auto import tqdm  # type: ignore[import-untyped]

            self._tqdm = tqdm(total=1000, desc=label, unit="‰", leave=False)
        except Exception:
            self._tqdm = None
        self._label = label

    def update(self, fraction: float) -> None:
        done = int(round(1000 * max(0.0, min(1.0, fraction))))
        if done == self._last:
            return
        if self._tqdm is not None:
            self._tqdm.update(done - max(self._last, 0))
        else:
            width = 30
            fill = done * width // 1000
            sys.stderr.write(f"\r{self._label} [{'#' * fill}{'.' * (width - fill)}] {done / 10:5.1f}%")
            sys.stderr.flush()
        self._last = done

    def close(self) -> None:
        if self._tqdm is not None:
            self._tqdm.close()
        else:
            sys.stderr.write("\n")
            sys.stderr.flush()
