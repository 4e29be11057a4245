"""Speed and memory benchmarks, each run side by side with a named peer (see docs/benchmarks.md)."""

from __future__ import annotations

import argparse
from dataclasses import dataclass


@dataclass(frozen=True)
class AtLeast:
    """The argparse type of a count option: a whole number no smaller than `minimum`, so that a
    benchmark given 0 rounds or -3 rows names the option before it builds anything."""

    minimum: int
    why: str = ""
    """Why the minimum is what it is, where it is not plain (said in the error)."""

    def __call__(self, text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if value < self.minimum:
            reason = f" ({self.why})" if self.why else ""
            raise argparse.ArgumentTypeError(
                f"must be at least {self.minimum}{reason}, got {value}"
            )
        return value


@dataclass(frozen=True)
class CountList:
    """The argparse type of a comma-separated list of counts (`2,4`), each at least `minimum`."""

    minimum: int

    def __call__(self, text: str) -> list[int]:
        return [AtLeast(self.minimum)(part.strip()) for part in text.split(",")]
