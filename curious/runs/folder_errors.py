"""What can be wrong with a run folder: one error family, so that a command catches every refusal
of a folder (`RunFolderError`) and tells a busy one (`RunFolderBusy`) or another run
(`ConfigMismatch`) apart where it acts on them."""

from __future__ import annotations

from typing import Any


class RunFolderError(RuntimeError):
    """A run folder that cannot be used as asked (nothing has been written)."""


class RunFolderBusy(RunFolderError):
    """Another process is training in the run folder right now."""


class ConfigMismatch(RunFolderError):
    """The folder holds another run than the config given (`RunFolder.check_resumable`)."""

    def __init__(self, message: str, differences: dict[str, tuple[Any, Any]]) -> None:
        super().__init__(message)
        self.differences = differences
        """Setting -> (value in config.json, value given); None for a side that lacks it."""
