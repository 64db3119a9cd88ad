"""The ``softtrack`` commands, one module per group; :mod:`softtrack.cli` assembles them."""
