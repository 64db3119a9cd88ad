"""The ``softtrack`` command line (Typer). Thin: it parses, calls :mod:`softtrack.api`, prints.

Every error a user can cause (a bad spec, a bad override, a missing run) is printed as one
line on stderr, ``error: <file>: <field>: <problem>; <fix>``, with exit code 2 and no traceback.

The commands live in :mod:`softtrack.commands`, one module per group, imported here in the
order ``softtrack --help`` lists them; :mod:`softtrack.commands.common` holds the app and what
the commands share.
"""

from __future__ import annotations

# each module registers its commands; imported in the order `softtrack --help` lists them
from softtrack.commands import spec_commands  # noqa: F401

# isort: split
from softtrack.commands import train_commands  # noqa: F401

# isort: split
from softtrack.commands import results_commands  # noqa: F401

# isort: split
from softtrack.commands import evaluate_commands  # noqa: F401

# isort: split
from softtrack.commands import report_commands  # noqa: F401

# isort: split
from softtrack.commands import workspace_commands  # noqa: F401

# isort: split
from softtrack.commands.common import TrajectoryChoice, app, exit_on_sigterm

__all__ = ["TrajectoryChoice", "app", "exit_on_sigterm"]

if __name__ == "__main__":  # python -m softtrack.cli
    app()
