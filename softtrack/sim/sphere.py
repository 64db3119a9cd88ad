"""A rigid sphere between the arms: its settings, their checks and the contact's stability.

The sphere is PyElastica 1.0.0's ``Sphere`` (mass m = ρ·4/3·πR³, inertia 2/5·m·R² about every
axis, frame = identity at the start) touching each arm through ``RodSphereContact``; the
integration is in :mod:`softtrack.sim.sphere_contact` (docs/physics.md, "A rigid object").
This module loads without numba.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from softtrack.numbers import is_finite_number, out_of_range, setting
from softtrack.sim.rod_properties import RodProperties
from softtrack.sim.stability import mode_is_stable

__all__ = ["SphereParams"]

#: Largest overlap of the sphere with an arm at rest that counts as "touching", m.
_REST_OVERLAP_TOLERANCE = 1e-9


@dataclass(frozen=True)
class SphereParams:
    """A rigid sphere and its contact with the arms (SI units).

    Attributes:
        radius: R, m.
        density: ρ, kg/m³.
        center: the centre at a reset, m.
        contact_k: stiffness of the contact with each arm (``RodSphereContact`` k), N/m.
        contact_nu: damping of that contact (``RodSphereContact`` nu), N·s/m.
        velocity_damping: the friction's slip damping c_v (``velocity_damping_coefficient``),
            N·s/m: below the Coulomb limit the friction force is c_v·|slip velocity|.
        friction: the Coulomb friction coefficient μ (``friction_coefficient``).

    The defaults are those of the transport task (docs/physics.md, "A rigid object"): a
    0.05-m ball of 500 kg/m³ (0.26 kg) at the tips' height between the straight arms, where it
    just touches both; a contact stiff enough that a 20-N squeeze overlaps 0.2 mm, damped to
    about a third of critical; friction that holds the ball's weight with a squeeze of ~3 N.
    """

    radius: float = setting(0.05, "m", gt=0)
    density: float = setting(500.0, "kg/m³", gt=0)
    center: tuple[float, float, float] = setting((0.0, 0.975, 0.0), "m", number=False)
    contact_k: float = setting(1.0e5, "N/m", ge=0)
    contact_nu: float = setting(100.0, "N·s/m", ge=0)
    velocity_damping: float = setting(100.0, "N·s/m", ge=0)
    friction: float = setting(0.5, ge=0)

    @property
    def volume(self) -> float:
        """4/3·πR³, m³."""
        return 4.0 / 3.0 * math.pi * self.radius**3

    @property
    def mass(self) -> float:
        """kg."""
        return self.volume * self.density

    @property
    def inertia(self) -> float:
        """2/5·m·R², kg·m² (about every axis)."""
        return 2.0 / 5.0 * self.mass * self.radius**2

    def kernel_params(self) -> np.ndarray:
        """(7,) the engine's ``sphere_params``: R, m, J, k, ν, c_v, μ."""
        return np.array(
            [
                self.radius,
                self.mass,
                self.inertia,
                self.contact_k,
                self.contact_nu,
                self.velocity_damping,
                self.friction,
            ],
            dtype=np.float64,
        )

    @classmethod
    def from_mapping(cls, values: object) -> SphereParams:
        """A sphere from a mapping of field names (a spec's ``sphere:`` section).

        Raises:
            ValueError: not a mapping, or an unknown name.
        """
        if isinstance(values, SphereParams):
            return values
        if not isinstance(values, dict):
            raise ValueError(f"sphere={values!r} must be a mapping of sphere fields")
        names = set(cls.__dataclass_fields__)
        unknown = sorted(set(values) - names)
        if unknown:
            raise ValueError(
                f"unknown sphere field {unknown[0]!r}; valid names: {', '.join(sorted(names))}"
            )
        fields = dict(values)
        if "center" in fields:
            fields["center"] = tuple(float(c) for c in fields["center"])
        return cls(**fields)

    def problems(self, params: RodProperties) -> str | None:
        """The first thing wrong with this sphere in the scene ``params``, as one sentence
        naming the field and the fix; None if it is valid."""
        problem = out_of_range(self, "sphere ")
        if problem is not None:
            return problem
        if len(self.center) != 3 or not all(is_finite_number(c) for c in self.center):
            return f"sphere center={self.center!r} must be a finite (x, y, z) point"
        if self.contact_k == 0.0:
            for name in ("contact_nu", "velocity_damping", "friction"):
                if getattr(self, name) != 0.0:
                    return (
                        f"sphere {name}={getattr(self, name)!r} needs contact between the arms "
                        "and the sphere: set sphere contact_k > 0 (e.g. 1e5 N/m) or "
                        f"{name}: 0"
                    )
        if params.n_arms != 2:
            return f"a sphere needs the two-arm scene, but there are {params.n_arms} arms"
        overlap = self.rest_overlap(params)
        if overlap > _REST_OVERLAP_TOLERANCE:
            largest = self.radius - overlap
            fix = (
                f"move the centre or use a radius ≤ {largest:.4g} m"
                if largest > 0
                else "move the centre off the arms (it lies on or inside one)"
            )
            return (
                f"sphere center={tuple(self.center)} overlaps an arm at rest by "
                f"{overlap * 1e3:.3g} mm; {fix}"
            )
        return self._stability_problem(params)

    def rest_overlap(self, params: RodProperties) -> float:
        """The deepest overlap of the sphere with the straight arms at rest, m (≤ 0: apart)."""
        center = np.asarray(self.center, dtype=float)
        direction = np.asarray(params.direction, dtype=float)
        deepest = -math.inf
        for base in params.base_positions:
            start = np.asarray(base, dtype=float)
            along = float(np.clip((center - start) @ direction, 0.0, params.length))
            distance = float(np.linalg.norm(center - (start + along * direction)))
            deepest = max(deepest, params.radius + self.radius - distance)
        return deepest

    def _stability_problem(self, params: RodProperties) -> str | None:
        share = self._mode_share(params)
        normal = (np.array([[share * self.contact_k]]), np.array([[share * self.contact_nu]]))
        slip = (np.zeros((1, 1)), np.array([[share * self.velocity_damping]]))
        if not mode_is_stable(*slip, params.dt):
            limit = 2.0 / (share * params.dt)
            return (
                f"sphere velocity_damping={self.velocity_damping:g} N·s/m makes the friction "
                f"unstable at dt={params.dt:g} s; use velocity_damping < {limit:.3g} N·s/m"
            )
        if not mode_is_stable(*normal, params.dt):
            return (
                f"sphere contact_k={self.contact_k:g} N/m with contact_nu={self.contact_nu:g} "
                f"N·s/m exceeds the explicit stability limit of the sphere's contact at "
                f"dt={params.dt:g} s; use contact_k ≤ {self.stiffness_limit(params):.3g} N/m, "
                "a smaller contact_nu or a smaller dt"
            )
        return None

    def _mode_share(self, params: RodProperties) -> float:
        """Inverse effective mass of the contact mode, 1/kg: a node between two touching
        elements takes ½ + ½ of k·γ (1/m_node), and the sphere takes the full k·γ of up to two
        elements of each arm (4/m)."""
        node_mass = params.density * params.area * params.length / params.n_elem
        return 1.0 / node_mass + 4.0 / self.mass

    def stiffness_limit(self, params: RodProperties) -> float:
        """The largest contact_k (N/m) stable at ``params.dt`` with this contact_nu, to 1e-4
        relative; 0 when the damping alone is unstable."""
        share = self._mode_share(params)

        def stable(k: float) -> bool:
            return mode_is_stable(
                np.array([[share * k]]), np.array([[share * self.contact_nu]]), params.dt
            )

        if not stable(0.0):
            return 0.0
        lo, hi = 0.0, 4.0 / (share * params.dt**2)
        while hi - lo > 1e-4 * hi:
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if stable(mid) else (lo, mid)
        return lo
