"""Old module paths of moved modules, so that files pickled before the move keep loading.

Saved models (``model.zip``: SB3/sbx pickle their policy class, replay buffer class and, for
per-arm networks, the actor and critic modules) and replay buffers (``replay_buffer.pkl``)
name classes by module path. The research variants moved to :mod:`softtrack.rl.variants`, so
files written before then name modules that no longer exist; :data:`MOVED_MODULES` maps each
old name to its new module. :func:`install` (run when :mod:`softtrack.rl` is imported, which
unpickling any of these names does first) adds an import hook that answers an import of an
old name with the new module itself: ``softtrack.rl.per_arm_td3.PerArmTD3Policy`` *is*
``softtrack.rl.variants.per_arm.PerArmTD3Policy``. The new module is imported only then, so
importing :mod:`softtrack.rl` stays light. Files written since name the new modules.

This is the one place for such aliases: add a line to :data:`MOVED_MODULES` when a module
whose classes end up in saved files moves.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
from importlib.machinery import ModuleSpec
from types import ModuleType

__all__ = ["MOVED_MODULES", "install"]

MOVED_MODULES: dict[str, str] = {
    "softtrack.rl.per_arm_td3": "softtrack.rl.variants.per_arm",
    "softtrack.rl.mirror": "softtrack.rl.variants.mirror",
}
"""Old module name → the module now holding its contents."""


class _MovedModuleFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds the old names of :data:`MOVED_MODULES` and loads each as its new module."""

    def find_spec(
        self, fullname: str, path: object = None, target: object = None
    ) -> ModuleSpec | None:
        if fullname not in MOVED_MODULES:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec: ModuleSpec) -> ModuleType:
        return importlib.import_module(MOVED_MODULES[spec.name])

    def exec_module(self, module: ModuleType) -> None:
        """Nothing to run: the new module is already imported."""


_FINDER = _MovedModuleFinder()


def install() -> None:
    """Add the import hook of :data:`MOVED_MODULES` (once)."""
    if _FINDER not in sys.meta_path:
        sys.meta_path.insert(0, _FINDER)
