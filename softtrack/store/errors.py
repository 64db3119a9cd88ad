"""The store's user-facing error (a module of its own, so light modules can raise it)."""

from __future__ import annotations

__all__ = ["RunStoreError"]


class RunStoreError(Exception):
    """A user-facing problem with the run store; the message is one line with the fix."""
