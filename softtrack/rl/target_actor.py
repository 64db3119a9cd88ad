"""Acting with TD3's target actor, the Polyak average of the actor's weights.

TD3 (and DDPG) keep a target actor that follows the actor by ``tau`` per update, a running
average over the last ~1/tau updates. With ``algo.act_with_target_actor: true`` that average is
the policy that validation scores, that ``best/`` keeps, that evaluation and export use: the
actor itself swings from checkpoint to checkpoint (docs/results/time-to-accuracy.md, "Levers
screened"), the average much less. Training is unchanged; the saved model files hold both.

Both backends: sbx (``policy.actor_state.target_params``) and Stable-Baselines3
(``policy.actor_target``). An exported sbx model keeps only the weights it acts with (its
``target_params`` are ``None``): it already acts with them, and nothing is swapped.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["act_with_target_actor", "acting_with_target_actor"]


def _swapped(policy: Any) -> bool:
    """Swap ``policy``'s acting weights with its target actor's; ``False`` if it has none."""
    state = getattr(policy, "actor_state", None)
    if state is not None:  # sbx
        if getattr(state, "target_params", None) is None:
            return False
        policy.actor_state = state.replace(params=state.target_params, target_params=state.params)
        return True
    target = getattr(policy, "actor_target", None)
    if target is None:  # an algorithm without a target actor
        return False
    policy.actor, policy.actor_target = target, policy.actor
    return True


def act_with_target_actor(model: Any) -> None:
    """Make a loaded ``model`` act with its target actor, for good (nothing if it has none)."""
    _swapped(model.policy)


@contextmanager
def acting_with_target_actor(model: Any, enabled: bool = True) -> Iterator[None]:
    """While inside, a training ``model`` acts with its target actor; its own weights come
    back on exit, so training goes on unchanged. ``enabled=False``: nothing changes."""
    swapped = enabled and _swapped(model.policy)
    try:
        yield
    finally:
        if swapped:
            _swapped(model.policy)
