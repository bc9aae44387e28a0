r"""Vessel particulars as one input: main dimensions, mass, inertia, CG, density, speed, propeller, rudder.

A :class:`Vessel` holds what is known about the craft before any fit; every model declares which of
its parameters are particulars (``PARTICULARS = {parameter: quantity}``, :mod:`diffship.models`) and
:meth:`Vessel.apply` (or ``model.with_vessel(vessel)``) sets them. The quantities a vessel computes are
listed in :data:`QUANTITIES`; derived ones say how they were derived:

* ``mass`` — given, else :math:`\rho\nabla`;
* inertias — given as moments (``inertia``) or radii of gyration (``gyration``) about the CG or the
  origin (``inertia_about``), moved by the parallel-axis theorem: :math:`I_{z,O} = I_{z,G} + m(x_G^2 + y_G^2)`;
* ``weight`` :math:`mg`, ``buoyancy`` :math:`\rho g\nabla`;
* prime added masses of the polynomial models (``added_mass_prime``), else estimated from L, B, T, C_B
  by Clarke, Gedling & Hine (1983): :math:`-Y'_{\dot v} = \pi(T/L)^2(1 + 0.16C_BB/T - 5.1(B/L)^2)`,
  :math:`-Y'_{\dot r} = \pi(T/L)^2(0.67B/L - 0.0033(B/T)^2)`, :math:`-N'_{\dot v} = \pi(T/L)^2(1.1B/L - 0.041B/T)`,
  :math:`-N'_{\dot r} = \pi(T/L)^2(1/12 + 0.017C_BB/T - 0.33B/L)`, and surge by Brix (1993),
  :math:`-X_{\dot u} = m/(\pi\sqrt{L^3/\nabla} - 14)`.

**File format** (JSON; ``src/diffship/vessels/*.json`` are the bundled reference vessels, loaded by name:
``mariner``, ``kvlcc2_model``, ``kvlcc2_full``, ``sspa_model``, ``usv``, ``bluerov2``). SI units only
(``"units": "SI"`` is required): lengths [m], mass [kg], volume [m³], density [kg/m³], speed [m/s],
inertia [kg m²], propeller speed [1/s]. Positions from the vessel's ``origin`` (a words field; the
3-DOF models' origin: midship for ``mmg``, the CO of the others), x forward, y starboard, z down.
Unknown values are ``null``; unknown keys are an error (a typo must not pass silently)::

    {"name": "my_ship", "units": "SI", "length": 7.0, "beam": 1.27, "draught": 0.46,
     "block_coefficient": 0.81, "displacement": 3.27, "mass": 3272.0, "rho": 1000.0,
     "origin": "midship", "cg": [0.24, 0.0, null], "inertia_about": "CG", "gyration": [null, null, 1.74],
     "approach_speed": 1.18, "scale": 45.7,
     "propeller": {"diameter": 0.216, "x": -3.36, "wake_fraction": 0.4, "thrust_deduction": 0.22,
                   "kt": [0.293, -0.275, -0.139], "rps": 10.23},
     "rudder": {"area": 0.0539, "span": 0.345, "x": -3.5}}

**Plausibility** (:func:`plausibility`, before any compute): the data's speed against the approach
speed, the Froude number :math:`F_n = U/\sqrt{gL}`, mass against :math:`\rho\nabla`, scale against length.

References:
    I. W. Clarke, P. Gedling, G. Hine, "The application of manoeuvring criteria in hull design using
    linear theory", Trans. RINA 125 (1983) 45–68. J. Brix (ed.), *Manoeuvring Technical Manual*, Seehafen
    Verlag 1993. SIMMAN 2008 (KVLCC2 particulars), http://www.simman2008.dk.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ModelError
from .models import AbstractModel, OpenWaterPropeller
from .params import ParamSpec
from .particulars import QUANTITIES, bundled_vessels, missing_message

__all__ = ["QUANTITIES", "Particulars", "Propeller", "Rudder", "Vessel", "bundled_vessels", "data_speed",
           "fixed_values", "fixed_values_text", "load_vessel", "particulars", "plausibility", "propeller_map", "require_particulars",
           "speed_range"]

_DIR = Path(__file__).parent / "vessels"
G = 9.81

_XYZ = tuple[float | None, float | None, float | None]
_NONE3: _XYZ = (None, None, None)


def _num(v, what):
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ModelError(f"{what}: expected a finite number or null, got {v!r}")
    return float(v)


def _xyz(v, what) -> _XYZ:
    if v is None:
        return _NONE3
    if not isinstance(v, (list, tuple)) or len(v) != 3:
        raise ModelError(f"{what}: expected [x, y, z] (numbers or null), got {v!r}")
    return tuple(_num(a, f"{what}[{i}]") for i, a in enumerate(v))  # type: ignore[return-value]


def _fields(cls, d: Mapping[str, Any], where: str) -> dict[str, Any]:
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(d) - names)
    if unknown:
        raise ModelError(f"{where}: unknown key(s) {', '.join(unknown)}; allowed: {', '.join(sorted(names))}")
    return dict(d)


@dataclasses.dataclass(frozen=True)
class Propeller:
    """Propeller data: diameter [m], position ``x`` from the origin [m], wake fraction and thrust
    deduction in straight motion, open-water ``kt`` = (k0, k1, k2, ...) of
    :math:`K_T(J) = \\sum_i k_i J^i`, approach propeller speed ``rps`` [1/s], ``count`` propellers."""

    diameter: float | None = None
    x: float | None = None
    wake_fraction: float | None = None
    thrust_deduction: float | None = None
    kt: tuple[float, ...] | None = None
    rps: float | None = None
    count: int = 1

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], where: str) -> Propeller:
        d = _fields(cls, d, f"{where}: propeller")
        kt = d.pop("kt", None)
        kw = {k: _num(v, f"{where}: propeller.{k}") for k, v in d.items() if k != "count"}
        if kt is not None:
            kw["kt"] = tuple(_num(c, f"{where}: propeller.kt") for c in kt)
        return cls(**kw, count=int(d.get("count", 1)))


@dataclasses.dataclass(frozen=True)
class Rudder:
    """Rudder data: area [m²], span [m], position ``x`` from the origin [m]."""

    area: float | None = None
    span: float | None = None
    x: float | None = None

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], where: str) -> Rudder:
        d = _fields(cls, d, f"{where}: rudder")
        return cls(**{k: _num(v, f"{where}: rudder.{k}") for k, v in d.items()})


@dataclasses.dataclass(frozen=True)
class Vessel:
    """The particulars of one craft (module docstring); ``None`` where unknown. SI units throughout."""

    name: str
    units: str = "SI"
    description: str = ""
    source: str = ""
    notes: tuple[str, ...] = ()
    length: float | None = None
    beam: float | None = None
    draught: float | None = None
    block_coefficient: float | None = None
    displacement: float | None = None  # volume ∇ [m³]
    mass: float | None = None
    rho: float | None = None
    g: float = G
    origin: str = "midship"
    cg: _XYZ = _NONE3
    cb: _XYZ = _NONE3
    inertia_about: str = "CG"
    inertia: _XYZ = _NONE3  # moments of inertia Ixx, Iyy, Izz [kg m²]
    gyration: _XYZ = _NONE3  # radii of gyration [m]
    approach_speed: float | None = None
    scale: float = 1.0  # λ: model at 1:λ (1 = full scale)
    full_scale_length: float | None = None
    propeller: Propeller | None = None
    rudder: Rudder | None = None
    added_mass_prime: Mapping[str, float] = dataclasses.field(default_factory=dict)

    # -- loading ------------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, d: Mapping[str, Any], where: str = "vessel") -> Vessel:
        d = _fields(cls, d, where)
        if not str(d.get("units", "")).startswith("SI"):
            raise ModelError(f"{where}: 'units' must be \"SI\" (m, kg, m3, kg/m3, m/s, kg m2); convert the values "
                             "and add \"units\": \"SI\"")
        if not d.get("name"):
            raise ModelError(f"{where}: a vessel needs a 'name'")
        kw: dict[str, Any] = {}
        for k, v in d.items():
            if k in ("name", "units", "description", "source", "origin"):
                kw[k] = str(v)
            elif k == "notes":
                kw[k] = tuple(str(n) for n in v)
            elif k in ("cg", "cb", "inertia", "gyration"):
                kw[k] = _xyz(v, f"{where}: {k}")
            elif k == "inertia_about":
                if v not in ("CG", "origin"):
                    raise ModelError(f"{where}: inertia_about must be \"CG\" or \"origin\", got {v!r}")
                kw[k] = v
            elif k == "propeller":
                kw[k] = None if v is None else Propeller.from_dict(v, where)
            elif k == "rudder":
                kw[k] = None if v is None else Rudder.from_dict(v, where)
            elif k == "added_mass_prime":
                kw[k] = {str(n): _num(x, f"{where}: added_mass_prime.{n}") for n, x in (v or {}).items()}
            else:
                kw[k] = _num(v, f"{where}: {k}")
                if kw[k] is None and k in ("g", "scale"):
                    kw.pop(k)
        for k in ("length", "beam", "draught", "displacement", "mass", "rho", "approach_speed", "scale"):
            if kw.get(k) is not None and kw[k] <= 0:
                raise ModelError(f"{where}: {k} must be positive, got {kw[k]}")
        return cls(**kw)

    @classmethod
    def from_json(cls, path: str | os.PathLike) -> Vessel:
        path = Path(path)
        try:
            d = json.loads(path.read_text())
        except FileNotFoundError:
            raise ModelError(f"vessel file {path} not found; give a JSON file or one of: "
                             f"{', '.join(bundled_vessels())}") from None
        except json.JSONDecodeError as exc:
            raise ModelError(f"vessel file {path}: not valid JSON ({exc})") from None
        if not isinstance(d, dict):
            raise ModelError(f"vessel file {path}: expected a JSON object")
        return cls.from_dict(d, f"vessel file {path}")

    # -- quantities ---------------------------------------------------------------------------------
    def quantity(self, key: str) -> tuple[float | None, str]:
        """``(value, how)`` of a :data:`QUANTITIES` key; ``(None, why)`` where the vessel does not give it."""
        if key not in QUANTITIES:
            raise ModelError(f"unknown vessel quantity {key!r}; known: {', '.join(QUANTITIES)}")
        fn = getattr(self, f"_q_{key}", None)
        if fn is not None:
            return fn()
        derived = {
            "Ixx_cg": lambda: self._inertia_cg(0), "Iyy_cg": lambda: self._inertia_cg(1), "Izz_cg": lambda: self._inertia_cg(2),
            "thrust_deduction": lambda: self._prop("thrust_deduction"), "wake_fraction": lambda: self._prop("wake_fraction"),
            "propeller_diameter": lambda: self._prop("diameter"), "kt0": lambda: self._prop("kt", 0),
            "kt1": lambda: self._prop("kt", 1), "kt2": lambda: self._prop("kt", 2),
            "propeller_x_L": lambda: self._over_L(*self._prop("x")),
            "rudder_area": lambda: (self.rudder.area if self.rudder else None, "rudder.area"),
            "rudder_span": lambda: (self.rudder.span if self.rudder else None, "rudder.span"),
            "rudder_x_L": lambda: self._over_L(self.rudder.x if self.rudder else None, "rudder.x"),
            **{f"{n}_prime": (lambda n=n: self._clarke(n)) for n in ("Xudot", "Yvdot", "Yrdot", "Nvdot", "Nrdot")}}
        if key in derived:
            return derived[key]()
        simple = {"length": self.length, "beam": self.beam, "draught": self.draught, "rho": self.rho,
                  "approach_speed": self.approach_speed}
        if key in simple:
            return simple[key], key
        if key in ("xG", "yG", "zG", "xB", "yB", "zB"):
            v = (self.cg if key[1] == "G" else self.cb)["xyz".index(key[0])]
            return v, ("cg" if key[1] == "G" else "cb") + f"[{'xyz'.index(key[0])}]"
        return None, "not a vessel-file quantity"

    def _q_mass(self):
        if self.mass is not None:
            return self.mass, "mass"
        if self.displacement is not None and self.rho is not None:
            return self.rho * self.displacement, "rho × displacement"
        return None, "needs mass, or displacement and rho"

    def _inertia_cg(self, i: int) -> tuple[float | None, str]:
        m, _ = self._q_mass()
        axis = "xyz"[i]
        if self.inertia[i] is not None:
            val, how = self.inertia[i], f"inertia[{i}]"
        elif self.gyration[i] is not None and m is not None:
            val, how = m * self.gyration[i] ** 2, f"mass × gyration[{i}]²"
        else:
            return None, f"needs inertia[{i}] or gyration[{i}] and mass"
        if self.inertia_about == "origin":
            others = [self.cg[j] for j in range(3) if j != i]
            if m is None or any(c is None for c in others):
                return None, f"inertia about the origin needs mass and the CG offsets to move I{axis}{axis} to the CG"
            val, how = val - m * sum(c * c for c in others), how + " moved from the origin to the CG"
        return val, how

    def _q_Izz_origin(self):
        izg, how = self._inertia_cg(2)
        m, _ = self._q_mass()
        if izg is None or m is None or self.cg[0] is None:
            return None, "needs the yaw inertia, mass and cg[0]"
        yg = self.cg[1] or 0.0
        return izg + m * (self.cg[0] ** 2 + yg * yg), how + " + m(xG² + yG²)"

    def _q_kzz_L(self):
        izg, _ = self._inertia_cg(2)
        m, _ = self._q_mass()
        if izg is None or m is None or self.length is None:
            return None, "needs the yaw inertia, mass and length"
        if self.inertia[2] is None and self.gyration[2] is not None and self.inertia_about == "CG":
            return self.gyration[2] / self.length, "gyration[2] / length"
        return math.sqrt(izg / m) / self.length, "sqrt(Izz_cg / m) / length"

    def _q_weight(self):
        m, how = self._q_mass()
        return (m * self.g, f"g × {how}") if m is not None else (None, how)

    def _q_buoyancy(self):
        if self.displacement is None or self.rho is None:
            return None, "needs displacement and rho"
        return self.rho * self.g * self.displacement, "rho g displacement"

    def _prop(self, attr, i=None):
        p = self.propeller
        v = getattr(p, attr) if p is not None else None
        if i is not None:
            v = v[i] if v is not None and len(v) > i else (0.0 if v is not None else None)
        return v, f"propeller.{attr}" + (f"[{i}]" if i is not None else "")

    def _q_one_minus_t(self):
        t, how = self._prop("thrust_deduction")
        return (1.0 - t, "1 − " + how) if t is not None else (None, "needs propeller.thrust_deduction")

    def _over_L(self, v, how):
        if v is None or self.length is None:
            return None, f"needs {how} and length"
        return v / self.length, f"{how} / length"

    def _clarke(self, key):
        if key in self.added_mass_prime:
            return self.added_mass_prime[key], f"added_mass_prime.{key}"
        L, B, T, CB = self.length, self.beam, self.draught, self.block_coefficient
        if key == "Xudot":
            m, _ = self._q_mass()
            if None in (m, L, self.displacement, self.rho):
                return None, "needs added_mass_prime.Xudot, or mass, length, displacement and rho (Brix)"
            xud = -m / (math.pi * math.sqrt(L**3 / self.displacement) - 14.0)
            return xud / (0.5 * self.rho * L**3), "Brix (1993) from mass, L and displacement"
        if None in (L, B, T, CB):
            return None, f"needs added_mass_prime.{key}, or length, beam, draught and block_coefficient (Clarke)"
        k = -math.pi * (T / L) ** 2
        val = {"Yvdot": k * (1 + 0.16 * CB * B / T - 5.1 * (B / L) ** 2),
               "Yrdot": k * (0.67 * B / L - 0.0033 * (B / T) ** 2),
               "Nvdot": k * (1.1 * B / L - 0.041 * B / T),
               "Nrdot": k * (1 / 12 + 0.017 * CB * B / T - 0.33 * B / L)}[key]
        return val, "Clarke et al. (1983) from L, B, T, C_B"

    # -- models ---------------------------------------------------------------------------------
    def apply(self, model: AbstractModel) -> AbstractModel:
        """``model`` with every particular set from this vessel (:class:`ModelError` naming any missing).

        A 6-DOF model gets ``rigid_body_cg=True`` when the vessel's CG is off its origin.
        """
        return require_particulars(model, self)[0]


@dataclasses.dataclass(frozen=True)
class Particulars:
    """What a vessel (and the command line) says about a model's particulars."""

    values: dict[str, float]  # parameter -> value from the vessel
    sources: dict[str, str]  # parameter -> where the value came from
    missing: tuple[str, ...]  # parameters neither the vessel, nor --fix, nor --free sets

    def missing_message(self, model: AbstractModel, vessel: Vessel | None = None) -> str:
        return missing_message(model.name, model.PARTICULARS, model.REFERENCE_VESSEL, self.missing,
                               vessel.name if vessel is not None else None)


def particulars(model: AbstractModel, vessel: Vessel | None, fixed: Iterable[str] = (),
                freed: Iterable[str] = ()) -> Particulars:
    """Values of ``model.PARTICULARS`` from ``vessel``; the ones set by neither it, ``fixed`` nor ``freed``
    are ``missing``."""
    fixed, freed = set(fixed), set(freed)
    values, sources, missing = {}, {}, []
    for name, key in model.PARTICULARS.items():
        if name in fixed:
            sources[name] = "--fix"
            continue
        if name in freed:
            sources[name] = "estimated (--free)"
            continue
        v, how = vessel.quantity(key) if vessel is not None else (None, "")
        if v is None:
            missing.append(name)
        else:
            values[name], sources[name] = float(v), f"vessel {vessel.name}: {how}"
    return Particulars(values, sources, tuple(missing))


def model_spec(name: str, vessel_path: str | None, fix_items: Iterable[str], init_items: Iterable[str],
               free: Iterable[str]):
    """What every command line does first (``--model``, ``--vessel``, ``--fix``, ``--init``, ``--free``):
    ``(model with its particulars, spec with free and fixed set, fix, init)``; an unknown parameter
    name, a missing particular or an ``--init`` of a parameter not estimated (its start value would become
    the value it is held at: :func:`diffship.cli_options.init_problem`) stops with one line naming it."""
    from .cli_options import init_problem
    from .models import get_model
    from .params import parse_assignments

    fix_items, init_items, free = list(fix_items), list(init_items), list(free)
    fix = parse_assignments(fix_items, "--fix")
    init = parse_assignments(init_items, "--init")
    model, _ = require_particulars(get_model(name), load_vessel(vessel_path) if vessel_path else None,
                                   fixed=fix, freed=free)
    spec = model.spec()
    for n in list(fix) + list(init) + free:
        spec[n]  # unknown names fail early, with the list of valid ones
    spec = spec.free(free).fix(fix)
    if (problem := init_problem(init_items, fix_items, spec)) is not None:
        raise ModelError(problem)
    return model, spec, fix, init


def require_particulars(model: AbstractModel, vessel: Vessel | None, fixed: Iterable[str] = (),
                        freed: Iterable[str] = ()) -> tuple[AbstractModel, Particulars]:
    """``model`` with its particulars from ``vessel``; a :class:`ModelError` naming every missing one."""
    p = particulars(model, vessel, fixed, freed)
    if p.missing:
        raise ModelError(p.missing_message(model, vessel))
    if vessel is None:
        return model, p
    out = model.with_params(p.values)
    if hasattr(out, "rigid_body_cg") and any(abs(c or 0.0) > 0 for c in vessel.cg) and not out.rigid_body_cg:
        out = dataclasses.replace(out, rigid_body_cg=True)
        p.sources["rigid_body_cg"] = f"vessel {vessel.name}: CG off the origin, full rigid-body terms"
    return out, p


# -- loading by name ------------------------------------------------------------------------------
def load_vessel(name_or_path: str | os.PathLike) -> Vessel:
    """A bundled vessel by name (:func:`bundled_vessels`) or a JSON vessel file."""
    s = str(name_or_path)
    if s in bundled_vessels():
        return Vessel.from_json(_DIR / f"{s}.json")
    if not s.endswith(".json") and not Path(s).exists():
        raise ModelError(f"--vessel {s}: neither a file nor a bundled vessel ({', '.join(bundled_vessels())})")
    return Vessel.from_json(s)


# -- plausibility --------------------------------------------------------------------------------
def _speeds(run) -> np.ndarray | None:
    if run.has("u"):
        return np.hypot(np.asarray(run["u"]), np.asarray(run["v"]) if run.has("v") else 0.0)
    if run.has("x0", "y0"):
        t = np.asarray(run.time)
        return np.hypot(np.gradient(np.asarray(run["x0"]), t), np.gradient(np.asarray(run["y0"]), t))
    return None


def data_speed(run) -> float | None:
    """Median speed of a run [m/s]: from ``u``, ``v`` when measured, else over ground from ``x0``, ``y0``."""
    s = _speeds(run)
    return float(np.median(s)) if s is not None else None


def speed_range(runs) -> tuple[float, float] | None:
    """5th and 95th percentiles of the speed over all samples of ``runs`` [m/s] (``None`` without speeds)."""
    s = [a for a in (_speeds(r) for r in runs) if a is not None]
    if not s:
        return None
    lo, hi = np.percentile(np.concatenate(s), [5.0, 95.0])
    return float(lo), float(hi)


def propeller_map(vessel: Vessel) -> OpenWaterPropeller:
    """The open-water propeller map (thrust from propeller speed ``n``) of a vessel's propeller data."""
    p = vessel.propeller
    need = {"propeller.diameter": p and p.diameter, "propeller.kt": p and p.kt, "rho": vessel.rho}
    missing = [k for k, v in need.items() if v is None]
    if missing:
        raise ModelError(f"vessel {vessel.name}: thrust from propeller speed needs {', '.join(missing)}")
    return OpenWaterPropeller(diameter=p.diameter, kt=tuple(p.kt), wake_fraction=p.wake_fraction or 0.0,
                              thrust_deduction=p.thrust_deduction or 0.0, rho=vessel.rho, count=p.count)


def plausibility(vessel: Vessel, runs: Sequence = (), model: AbstractModel | None = None) -> list[str]:
    """Warnings (``"warning: ..."``) and notes about the vessel and the data, before any compute."""
    out = []
    speeds = [s for s in (data_speed(r) for r in runs) if s is not None]
    U = float(np.median(speeds)) if speeds else None
    U0 = vessel.approach_speed
    if U is not None and U0 is not None:
        ratio = U / U0
        msg = f"data speed {U:.3g} m/s (median over {len(speeds)} run(s)) vs approach speed {U0:.3g} m/s of vessel {vessel.name}"
        out.append(f"warning: {msg}: ratio {ratio:.2g}; is this the right vessel, at the right scale?"
                   if not 0.5 <= ratio <= 2.0 else f"note: {msg}")
    if vessel.length is not None and (U or U0):
        fn = (U or U0) / math.sqrt(vessel.g * vessel.length)
        tag = "warning" if fn > 0.4 else "note"
        out.append(f"{tag}: Froude number {fn:.3g} (L {vessel.length:.4g} m)"
                   + ("; above 0.4 the craft leaves the displacement regime the 3-DOF models assume" if fn > 0.4 else ""))
    if vessel.mass is not None and vessel.displacement is not None and vessel.rho is not None:
        rv = vessel.rho * vessel.displacement
        dev = vessel.mass / rv - 1.0
        tag = "warning" if abs(dev) > 0.05 else "note"
        out.append(f"{tag}: mass {vessel.mass:.6g} kg vs rho × displacement {rv:.6g} kg ({100 * dev:+.1f} %)"
                   + ("; a floating hull has m = rho ∇: check the density or the units" if abs(dev) > 0.05 else ""))
    if vessel.scale != 1.0 and vessel.full_scale_length is not None and vessel.length is not None:
        implied = vessel.full_scale_length / vessel.length
        if abs(implied / vessel.scale - 1.0) > 0.02:
            out.append(f"warning: scale 1:{vessel.scale:.4g} but full-scale length / length = {implied:.4g}")
        else:
            out.append(f"note: model at scale 1:{vessel.scale:.4g} (full-scale L {vessel.full_scale_length:.4g} m)")
    rng = speed_range(runs)
    if model is not None and rng is not None and hasattr(model, "convention_warnings"):
        out += [f"warning: {w}" for w in model.convention_warnings(*rng)]
    return out


def fixed_values(spec: ParamSpec, sources: Mapping[str, str] | None = None) -> dict[str, dict]:
    """The fixed values a fit used, for the JSON report: ``{name: {"value", "unit", "source"}}``
    (SI units; the source is the vessel file entry, ``--fix``, or ``"model default"``), plus
    ``{"notes": {...}}`` for sources that are not parameters (e.g. a rigid-body option)."""
    sources = sources or {}
    out: dict[str, dict] = {p.name: {"value": float(p.value), "unit": p.unit, "source": sources.get(p.name, "model default")}
                            for p in spec.params if not p.free}
    notes = {k: v for k, v in sources.items() if k not in spec}
    if notes:
        out["notes"] = dict(notes)
    return out


def fixed_values_text(spec: ParamSpec, sources: Mapping[str, str] | None = None) -> str:
    """The fixed values a fit used, one per line with its unit and where it came from."""
    sources = sources or {}
    lines = ["fixed values (not estimated):"]
    for p in spec.params:
        if not p.free:
            src = sources.get(p.name, "model default")
            lines.append(f"  {p.name:<10} = {p.value:<14.6g} {p.unit:<8} {src}")
    extra = [f"  {k}: {v}" for k, v in sources.items() if k not in spec]
    return "\n".join(lines + extra) if len(lines) > 1 or extra else "fixed values: none"
