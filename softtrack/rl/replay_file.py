"""A checkpoint's replay buffer on disk, holding only the transitions it has.

Stable-Baselines3 pickles a replay buffer whole: its arrays are allocated for the full
capacity (``buffer_size``, 1e6 transitions: about 1.5 GB for the centralized task), so a
checkpoint early in a run, or of a short run, writes mostly zeros. :func:`save_replay_buffer`
pickles a buffer that is not yet full with each per-transition array (first axis of length
``buffer_size``) cut to the filled rows; :func:`load_replay_buffer` reads either form and pads
the cut arrays back with the zeros they had, so the reloaded buffer equals the saved one array
for array. A full buffer is pickled as Stable-Baselines3 does.
"""

from __future__ import annotations

import copy
import pickle
from pathlib import Path
from typing import Any

import numpy as np

#: Attribute of a cut buffer's pickle: the names of the cut arrays and the capacity to restore.
_CUT = "_softtrack_cut_arrays"


def save_replay_buffer(buffer: Any, path: Path) -> None:
    """Pickle ``buffer`` (a Stable-Baselines3 ``ReplayBuffer``) to ``path``, its per-transition
    arrays cut to the ``buffer.pos`` filled rows unless it is full."""
    if buffer.full:
        state = buffer
    else:
        state = copy.copy(buffer)  # shallow: the live buffer keeps its arrays
        cut = []
        for name, value in vars(buffer).items():
            if isinstance(value, np.ndarray) and value.ndim and len(value) == buffer.buffer_size:
                setattr(state, name, value[: buffer.pos])
                cut.append(name)
        setattr(state, _CUT, (tuple(cut), int(buffer.buffer_size)))
    with path.open("wb") as file:
        pickle.dump(state, file, protocol=pickle.HIGHEST_PROTOCOL)


def load_replay_buffer(model: Any, path: Path) -> None:
    """Load ``path`` (written by :func:`save_replay_buffer` or by Stable-Baselines3) into the
    off-policy ``model``, with every cut array padded back to the buffer's capacity."""
    model.load_replay_buffer(path)
    buffer = model.replay_buffer
    names, capacity = vars(buffer).pop(_CUT, ((), 0))
    for name in names:
        filled = getattr(buffer, name)
        full = np.zeros((capacity, *filled.shape[1:]), dtype=filled.dtype)
        full[: len(filled)] = filled
        setattr(buffer, name, full)
