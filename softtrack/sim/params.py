"""Physical and numerical parameters of the dual-arm Cosserat-rod scenario.

Defaults are the study's setting (``docs/physics.md``). Every field can be overridden, and
:meth:`SimParams.validate` rejects values that would crash or silently blow up the
integrator later (non-positive sizes, an unstable time step, ...).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from softtrack.numbers import out_of_range, setting
from softtrack.sim.sphere import SphereParams
from softtrack.sim.stability import (
    contact_mode,
    contact_stiffness_limit,
    mode_is_stable,
    stable_time_step_limit,
)

__all__ = [
    "CONTACT_ON",
    "MODEL_PARAMETERS",
    "STANDARD_GRAVITY",
    "InvalidParameterError",
    "RodConstants",
    "SimParams",
    "model_error_stability",
    "scaled_params",
]

STANDARD_GRAVITY = 9.81  # m/s², along −y when gravity is switched on

# "Contact on" (docs/physics.md, "Contact"): stiff enough that the arms overlap by at most
# ~5 mm when every control value presses them together at ±1 (tests/test_contact.py), damped
# enough that contact does not ring (a third of critical for one element pair), and well inside
# the contact's stability limits at dt = 2e-4 s (k ≤ 1.08e7 N/m at this ν; ν ≤ 1.58e3 N·s/m).
CONTACT_ON: dict[str, float] = {"contact_k": 1.0e6, "contact_nu": 600.0}


# Model error (env.realism): each factor's name → the SimParams field it multiplies. The order
# is that of the engine's per-environment factor arrays and of the random draws.
MODEL_PARAMETERS: dict[str, str] = {
    "youngs_modulus_scale": "youngs_modulus",
    "density_scale": "density",
    "radius_scale": "radius",
    "damping_scale": "damping",
    "torque_scale_factor": "torque_scale",
}
# The end of each factor's range that gives the smallest stable time step: the stiffest,
# lightest, thinnest and most damped rod (docs/environment.md, "Model error"); the torque scale
# does not enter the limit.
_WORST_END = {
    "youngs_modulus_scale": 1,
    "density_scale": 0,
    "radius_scale": 0,
    "damping_scale": 1,
    "torque_scale_factor": 0,
}


class InvalidParameterError(ValueError):
    """A simulation parameter is out of range; the message names the field and the fix."""


@dataclass(frozen=True)
class SimParams:
    """Settings of the clamped-rod scenario (SI units throughout).

    Attributes:
        n_elem: elements per arm (nodes = n_elem + 1).
        length: rest length of each arm, m.
        radius: cross-section radius, m.
        density: mass density ρ, kg/m³.
        youngs_modulus: E, Pa.
        poisson_ratio: ν; the shear modulus is G = E / (2 (1 + ν)).
        shear_correction: α_c in the shear stiffness α_c·G·A (PyElastica: 27/28).
        damping: ν_d, the PyElastica-0.1 dissipation coefficient, N·s/m².
        dt: integration time step, s.
        steps_per_action: integration steps per control step.
        gravity: gravitational acceleration along −y, m/s² (0 = off; ``True`` = 9.81).
        torque_scale: element torque at a control value of 1, N·m.
        base_positions: clamp position of each arm, m; its length is the number of arms.
        direction: rest tangent d₃ of every arm (unit vector).
        normal: rest normal d₁ of every arm (unit vector, orthogonal to ``direction``).
        contact_k: stiffness of the contact between the arms, N/m (PyElastica's
            ``RodRodContact`` k); 0 = off, the arms pass through each other (the study).
        contact_nu: damping of that contact, N·s/m (``RodRodContact`` nu); needs contact_k > 0.
        sphere: a rigid sphere touching the arms (:class:`~softtrack.sim.sphere.SphereParams`,
            two arms only); None (the default) = no object.
    """

    n_elem: int = setting(20, ge=2, whole=True)
    length: float = setting(1.0, "m", gt=0)
    radius: float = setting(0.05, "m", gt=0)
    density: float = setting(1000.0, "kg/m³", gt=0)
    youngs_modulus: float = setting(1.0e7, "Pa", gt=0)
    poisson_ratio: float = setting(0.5, gt=-1, le=0.5)
    shear_correction: float = setting(27.0 / 28.0, gt=0)
    damping: float = setting(30.0, "N·s/m²", ge=0)
    dt: float = setting(2.0e-4, "s", gt=0)
    steps_per_action: int = setting(10, ge=1, whole=True)
    gravity: float = setting(0.0, "m/s²")
    torque_scale: float = setting(75.0, "N·m")
    base_positions: tuple[tuple[float, float, float], ...] = setting(
        ((-0.1, 0.0, 0.0), (0.1, 0.0, 0.0)), "m", number=False
    )
    direction: tuple[float, float, float] = (0.0, 1.0, 0.0)
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    contact_k: float = setting(0.0, "N/m", ge=0)
    contact_nu: float = setting(0.0, "N·s/m", ge=0)
    sphere: SphereParams | None = None

    @classmethod
    def from_overrides(cls, **overrides: Any) -> SimParams:
        """Defaults with ``overrides`` applied, validated.

        Raises:
            InvalidParameterError: for an unknown name or an invalid value.
        """
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise InvalidParameterError(
                f"unknown simulation parameter {unknown[0]!r}; valid names: {', '.join(sorted(names))}"
            )
        if "gravity" in overrides and isinstance(overrides["gravity"], bool):
            overrides["gravity"] = STANDARD_GRAVITY if overrides["gravity"] else 0.0
        for key in ("base_positions",):
            if key in overrides:
                overrides[key] = tuple(tuple(float(c) for c in p) for p in overrides[key])
        for key in ("direction", "normal"):
            if key in overrides:
                overrides[key] = tuple(float(c) for c in overrides[key])
        if overrides.get("sphere") is not None:
            try:
                overrides["sphere"] = SphereParams.from_mapping(overrides["sphere"])
            except (TypeError, ValueError) as err:
                raise InvalidParameterError(str(err)) from None
        params = cls(**overrides)
        params.validate()
        return params

    # ---- derived quantities -------------------------------------------------------------
    @property
    def n_arms(self) -> int:
        return len(self.base_positions)

    @property
    def n_nodes(self) -> int:
        return self.n_elem + 1

    @property
    def shear_modulus(self) -> float:
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def area(self) -> float:
        return math.pi * self.radius**2

    @property
    def second_moment(self) -> float:
        """I₁ = I₂ = πr⁴/4, m⁴."""
        return math.pi * self.radius**4 / 4.0

    @property
    def bending_stiffness(self) -> float:
        """EI, N·m²."""
        return self.youngs_modulus * self.second_moment

    @property
    def control_dt(self) -> float:
        """Duration of one control step, s."""
        return self.dt * self.steps_per_action

    @property
    def dt_limit(self) -> float:
        """Largest stable time step of this discretisation and damping, s."""
        return stable_time_step_limit(self)

    def validate(self) -> None:
        """Raise :class:`InvalidParameterError` naming the first invalid field and the fix."""
        problem = out_of_range(self)
        if problem is not None:
            raise InvalidParameterError(problem)
        if self.n_arms < 1 or any(len(p) != 3 for p in self.base_positions):
            raise InvalidParameterError(
                "base_positions must be a list of (x, y, z) points, one per arm"
            )
        if not np.all(np.isfinite(np.asarray(self.base_positions, dtype=float))):
            raise InvalidParameterError(
                f"base_positions={self.base_positions!r} must contain finite coordinates"
            )
        d = np.asarray(self.direction, dtype=float)
        n = np.asarray(self.normal, dtype=float)
        if (
            d.shape != (3,)
            or n.shape != (3,)
            or not np.all(np.isfinite(d))
            or not np.all(np.isfinite(n))
        ):
            raise InvalidParameterError("direction and normal must be finite 3-vectors")
        if abs(np.linalg.norm(d) - 1) > 1e-9 or abs(np.linalg.norm(n) - 1) > 1e-9:
            raise InvalidParameterError("direction and normal must be unit vectors")
        if abs(float(d @ n)) > 1e-9:
            raise InvalidParameterError("normal must be orthogonal to direction")
        self._validate_contact()
        self._validate_sphere()
        limit = self.dt_limit
        if self.dt > limit:
            raise InvalidParameterError(
                f"dt={self.dt:g} s exceeds the explicit stability limit {limit:.3g} s of this "
                f"discretisation (n_elem={self.n_elem}, damping={self.damping:g}); "
                f"use dt ≤ {limit:.3g}"
            )

    def _validate_sphere(self) -> None:
        """The sphere's fields, its place at rest and its contact's stability."""
        if self.sphere is None:
            return
        if not isinstance(self.sphere, SphereParams):
            raise InvalidParameterError(
                f"sphere={self.sphere!r} must be a SphereParams (or None for no object)"
            )
        problem = self.sphere.problems(self)
        if problem is not None:
            raise InvalidParameterError(problem)

    def _validate_contact(self) -> None:
        """The contact fields: two arms, and a contact_k stable at dt."""
        if self.contact_k == 0.0:
            if self.contact_nu != 0.0:
                raise InvalidParameterError(
                    f"contact_nu={self.contact_nu!r} needs contact_k > 0: contact is off; "
                    f"set contact_k (e.g. {CONTACT_ON['contact_k']:g} N/m) or contact_nu: 0"
                )
            return
        if self.n_arms != 2:
            raise InvalidParameterError(
                f"contact_k={self.contact_k:g} needs two arms (contact is between arm 1 and "
                f"arm 2), but there are {self.n_arms}; set contact_k: 0"
            )
        if not mode_is_stable(*contact_mode(self), self.dt):
            limit = contact_stiffness_limit(self)
            if limit == 0.0:
                raise InvalidParameterError(
                    f"contact_nu={self.contact_nu:g} N·s/m makes the contact unstable at "
                    f"dt={self.dt:g} s whatever contact_k; lower contact_nu or dt"
                )
            raise InvalidParameterError(
                f"contact_k={self.contact_k:g} N/m with contact_nu={self.contact_nu:g} N·s/m "
                f"exceeds the explicit stability limit of the contact at dt={self.dt:g} s; "
                f"use contact_k ≤ {_floor_3g(limit):.3g} N/m or a smaller dt"
            )


@dataclass(frozen=True)
class RodConstants:
    """Per-arm constant arrays of the discretised rods (identical for every environment).

    Shapes use A = arms, N = elements. Only diagonals of the 3×3 tensors are stored.

    Attributes:
        rest_lengths: (N,) m.
        rest_voronoi_lengths: (N−1,) m.
        volume: (N,) m³.
        inv_mass: (N+1,) 1/kg, lumped node masses.
        mass: (N+1,) kg.
        inertia: (3, N) kg·m², diagonal of J = ρ·dl·diag(I₁, I₂, I₃).
        inv_inertia: (3, N) 1/(kg·m²).
        shear_stiffness: (3, N) N, diagonal of S = (α_c·G·A, α_c·G·A, E·A).
        bend_stiffness: (3, N−1) N·m², Voronoi length-weighted average of diag(E·I₁, E·I₂, G·I₃).
        base_position: (A, 3) m, clamped node-0 position.
        base_directors: (A, 3, 3) clamped element-0 directors (row r = d_{r+1}).
    """

    rest_lengths: np.ndarray
    rest_voronoi_lengths: np.ndarray
    volume: np.ndarray
    mass: np.ndarray
    inv_mass: np.ndarray
    inertia: np.ndarray
    inv_inertia: np.ndarray
    shear_stiffness: np.ndarray
    bend_stiffness: np.ndarray
    base_position: np.ndarray
    base_directors: np.ndarray
    rest_position: np.ndarray = field(repr=False)  # (A, 3, N+1) m, the straight rest shape

    @classmethod
    def build(cls, p: SimParams) -> RodConstants:
        n = p.n_elem
        dl = np.full(n, p.length / n)
        area = p.area
        i1 = p.second_moment
        i3 = 2.0 * i1
        volume = area * dl
        mass = np.zeros(n + 1)
        mass[:-1] += 0.5 * p.density * volume
        mass[1:] += 0.5 * p.density * volume
        inertia = np.stack([p.density * dl * i1, p.density * dl * i1, p.density * dl * i3])
        shear = np.tile(
            np.array(
                [
                    p.shear_correction * p.shear_modulus * area,
                    p.shear_correction * p.shear_modulus * area,
                    p.youngs_modulus * area,
                ]
            )[:, None],
            (1, n),
        )
        element_bend = np.tile(
            np.array([p.youngs_modulus * i1, p.youngs_modulus * i1, p.shear_modulus * i3])[:, None],
            (1, n),
        )
        bend = (element_bend[:, 1:] * dl[1:] + element_bend[:, :-1] * dl[:-1]) / (dl[1:] + dl[:-1])
        direction = np.asarray(p.direction, dtype=float)
        normal = np.asarray(p.normal, dtype=float)
        directors = np.stack([normal, np.cross(direction, normal), direction])
        bases = np.asarray(p.base_positions, dtype=float)
        s = np.linspace(0.0, p.length, n + 1)
        rest_position = bases[:, :, None] + direction[None, :, None] * s[None, None, :]
        return cls(
            rest_lengths=dl,
            rest_voronoi_lengths=0.5 * (dl[1:] + dl[:-1]),
            volume=volume,
            mass=mass,
            inv_mass=1.0 / mass,
            inertia=inertia,
            inv_inertia=1.0 / inertia,
            shear_stiffness=shear,
            bend_stiffness=bend,
            base_position=bases.copy(),
            base_directors=np.repeat(directors[None], len(bases), axis=0),
            rest_position=rest_position,
        )


def scaled_params(params: SimParams, factors: Mapping[str, float]) -> SimParams:
    """``params`` with the model-error factors applied (not validated).

    Args:
        params: the nominal settings.
        factors: some of :data:`MODEL_PARAMETERS`' names → factor (> 0); a missing name or a
            factor of exactly 1 leaves its field as it is (so all-ones give ``params`` itself,
            bit for bit).

    Raises:
        InvalidParameterError: an unknown name.
    """
    unknown = sorted(set(factors) - set(MODEL_PARAMETERS))
    if unknown:
        raise InvalidParameterError(
            f"unknown model-error factor {unknown[0]!r}; valid names: "
            + ", ".join(MODEL_PARAMETERS)
        )
    changes = {
        MODEL_PARAMETERS[name]: getattr(params, MODEL_PARAMETERS[name]) * float(factor)
        for name, factor in factors.items()
        if float(factor) != 1.0
    }
    return dataclasses.replace(params, **changes) if changes else params


def _floor_3g(value: float) -> float:
    """``value`` rounded *down* to 3 significant digits (a dt that is still stable)."""
    if value <= 0 or not math.isfinite(value):
        return value
    scale = 10.0 ** (math.floor(math.log10(value)) - 2)
    return math.floor(value / scale) * scale


def model_error_stability(
    params: SimParams, ranges: Mapping[str, tuple[float, float]]
) -> tuple[str, str, str] | None:
    """Check the time step against the worst case of the model-error ranges.

    The explicit stability limit (:attr:`SimParams.dt_limit`) falls with the Young's modulus
    and the damping and rises with the density and the radius, so the worst case of the ranges
    is the stiffest, lightest, thinnest, most damped rod: each factor at the end of its range
    that lowers the limit.

    Args:
        params: the nominal settings (their ``dt`` is checked).
        ranges: factor name → (low, high); a fixed factor is (f, f).

    Returns:
        ``None`` when ``params.dt`` is stable at the worst case, else (field, problem, fix):
        the factor whose worst end alone lowers the limit most, what is wrong, and how to fix it.
    """
    worst = {
        name: float(ranges[name][_WORST_END[name]])
        for name in ranges
        if name != "torque_scale_factor"
    }
    worst = {name: value for name, value in worst.items() if value != 1.0}
    if not worst:
        return None
    limit = scaled_params(params, worst).dt_limit
    if params.dt <= limit:
        return None
    # blame the factor that alone lowers the limit most
    field_name = min(worst, key=lambda name: scaled_params(params, {name: worst[name]}).dt_limit)
    low, high = ranges[field_name]
    value = worst[field_name]
    if low == high:
        where = f"= {value:g}"
    else:
        where = f"{'up to' if _WORST_END[field_name] else 'down to'} {value:g}"
    others = [f"{name} {value:g}" for name, value in worst.items() if name != field_name]
    problem = (
        f"{where} needs dt ≤ {limit:.4g} s (the explicit stability limit of the stiffest, "
        f"lightest rod{' with ' + ', '.join(others) if others else ''}), but dt = "
        f"{params.dt:g} s"
    )
    fix = f"lower dt to {_floor_3g(limit):.3g} s or narrow the range"
    return field_name, problem, fix
