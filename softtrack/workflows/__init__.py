"""What the commands do, step by step, over the packages that own the work: the functions
behind :mod:`softtrack.api` that call into several packages (evaluation, training, reports,
the store) for one command."""
