"""Progress reports of long calls (``progress=True`` of EM, ``fit`` and ``filter_batch``): a
tqdm bar on stderr when tqdm is installed, else one rewritten line on stderr."""

from __future__ import annotations

import sys
from typing import Any, Optional


class Progress:
    """``with Progress(on, total, desc) as p: ... p.update(1, loglik=...)``; nothing when off."""

    def __init__(self, on: bool, total: Optional[int], desc: str) -> None:
        self.on, self.total, self.desc, self.done = on, total, desc, 0
        self._bar: Any = None
        if on:
            try:
                from tqdm.auto import tqdm
            except ImportError:
                tqdm = None
            if tqdm is not None:
                self._bar = tqdm(total=total, desc=desc, file=sys.stderr, leave=True)

    def update(self, k: int = 1, **postfix: float) -> None:
        if not self.on:
            return
        self.done += k
        if self._bar is not None:
            self._bar.update(k)
            if postfix:
                self._bar.set_postfix({name: f"{v:.6g}" for name, v in postfix.items()}, refresh=False)
            return
        of = f"/{self.total}" if self.total is not None else ""
        extra = "".join(f"  {name} {v:.6g}" for name, v in postfix.items())
        print(f"\r{self.desc} {self.done}{of}{extra}", end="", file=sys.stderr, flush=True)

    def close(self) -> None:
        if not self.on:
            return
        if self._bar is not None:
            self._bar.close()
        else:
            print(file=sys.stderr)

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
