"""What each model needs to know about the vessel before a fit: its particulars. Plain Python, no JAX.

A model's *particulars* are the parameters that describe the vessel rather than its hydrodynamics:
mass, inertia and its reference point, main dimensions, water density, approach speed, propeller and
rudder data. Each model class declares them (``PARTICULARS = {parameter: quantity}``, the quantity a
:class:`diffship.vessel.Vessel` computes) and names its reference vessel (``REFERENCE_VESSEL``). The
declarations live here, in a module that imports neither JAX nor NumPy, so that
``python -m diffship.fit --model vmm_simple RUN.csv`` without ``--vessel`` stops with one line naming
what is missing before any numerical library is loaded (:func:`diffship.fit.args.precheck`); the model
classes take their class variables from :data:`MODEL_PARTICULARS` (one source; ``tests/test_vessel.py``
checks that every registered model agrees).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import NamedTuple

__all__ = ["QUANTITIES", "MODEL_PARTICULARS", "ModelNeeds", "bundled_vessels", "missing_message", "missing_particulars"]

_VESSELS = Path(__file__).parent / "vessels"

#: Vessel quantities a model's ``PARTICULARS`` can name: key -> "description [unit]".
QUANTITIES: dict[str, str] = {
    "mass": "mass [kg] (or displacement [m3] and rho)", "length": "length between perpendiculars [m]",
    "beam": "beam [m]", "draught": "draught [m]", "rho": "water density [kg/m3]",
    "approach_speed": "approach speed [m/s]", "xG": "CG x from the origin [m]", "yG": "CG y [m]", "zG": "CG z [m]",
    "xB": "CB x from the origin [m]", "yB": "CB y [m]", "zB": "CB z [m]",
    "Ixx_cg": "roll inertia about the CG [kg m2]", "Iyy_cg": "pitch inertia about the CG [kg m2]",
    "Izz_cg": "yaw inertia about the CG [kg m2]", "Izz_origin": "yaw inertia about the origin [kg m2]",
    "kzz_L": "yaw radius of gyration about the CG / L [-]", "weight": "weight m g [N]",
    "buoyancy": "buoyancy rho g displacement [N]", "one_minus_t": "1 - propeller thrust deduction [-]",
    "thrust_deduction": "propeller thrust deduction t [-]", "wake_fraction": "propeller wake fraction w [-]",
    "propeller_diameter": "propeller diameter [m]", "propeller_x_L": "propeller x from the origin / L [-]",
    "kt0": "open-water K_T(J) coefficient k0", "kt1": "open-water K_T coefficient k1",
    "kt2": "open-water K_T coefficient k2", "rudder_area": "rudder area [m2]", "rudder_span": "rudder span [m]",
    "rudder_x_L": "rudder x from the origin / L [-]",
    "Xudot_prime": "surge added mass X'_udot [-] (or L, displacement)",
    "Yvdot_prime": "sway added mass Y'_vdot [-] (or L, B, T, C_B)", "Yrdot_prime": "Y'_rdot [-] (or L, B, T, C_B)",
    "Nvdot_prime": "N'_vdot [-] (or L, B, T, C_B)", "Nrdot_prime": "yaw added inertia N'_rdot [-] (or L, B, T, C_B)",
    "dof_inertia": "total inertia of the decaying DOF, rigid + added [kg or kg m2]: --fix it",
    "dof_stiffness": "restoring stiffness of the decaying DOF [N m/rad]: --fix it",
}

# -- the declarations, per model class (parameter -> vessel quantity) ------------------------------
FOSSEN3 = {"m": "mass", "Iz": "Izz_origin", "xg": "xG"}
FOSSEN6 = {"m": "mass", "Ix": "Ixx_cg", "Iy": "Iyy_cg", "Iz": "Izz_cg", "xg": "xG", "yg": "yG", "zg": "zG",
           "xb": "xB", "yb": "yB", "zb": "zB", "W": "weight", "B": "buoyancy"}
MMG = {"L": "length", "B": "beam", "d": "draught", "m": "mass", "xG": "xG", "kzz": "kzz_L", "rho": "rho",
       "DP": "propeller_diameter", "xP": "propeller_x_L", "wP0": "wake_fraction", "tP": "thrust_deduction",
       "k0": "kt0", "k1": "kt1", "k2": "kt2", "AR": "rudder_area", "HR": "rudder_span", "xR": "rudder_x_L"}
VMM = {"m": "mass", "Iz": "Izz_origin", "xG": "xG", "L": "length", "rho": "rho", "U0": "approach_speed",
       "XT": "one_minus_t", "Xudot": "Xudot_prime", "Yvdot": "Yvdot_prime", "Yrdot": "Yrdot_prime",
       "Nvdot": "Nvdot_prime", "Nrdot": "Nrdot_prime"}
#: the DOF's total inertia is not a vessel-file quantity (which DOF decays is the test's): ``--fix m=VALUE``
DECAY1 = {"m": "dof_inertia"}
#: ``--fix`` both, or fix one and ``--free`` the other (the decay gives only k/I and b/I)
DECAY2 = {"I": "dof_inertia", "k": "dof_stiffness"}


class ModelNeeds(NamedTuple):
    """What a registered model (``--model KEY``) needs before a fit."""

    name: str  # the model's name (its ``name`` class variable)
    particulars: Mapping[str, str]  # parameter -> vessel quantity (:data:`QUANTITIES`)
    reference_vessel: str | None  # the bundled vessel whose particulars are the model's defaults


#: Every model selectable by ``--model KEY`` (the keys of :data:`diffship.models.MODELS`, in that order).
MODEL_PARTICULARS: dict[str, ModelNeeds] = {
    "nomoto1": ModelNeeds("nomoto1", {}, None),
    "nomoto2": ModelNeeds("nomoto2", {}, None),
    "fossen3": ModelNeeds("fossen3", FOSSEN3, "usv"),
    "fossen3_waterjet": ModelNeeds("fossen3", FOSSEN3, "usv"),
    "mmg": ModelNeeds("mmg", MMG, "kvlcc2_model"),
    "vmm_linear": ModelNeeds("vmm_linear", VMM, "mariner"),
    "vmm_simple": ModelNeeds("vmm_simple", VMM, "mariner"),
    "vmm_abkowitz": ModelNeeds("vmm_abkowitz", VMM, "mariner"),
    "fossen6": ModelNeeds("fossen6", FOSSEN6, "bluerov2"),
    "decay1": ModelNeeds("decay1", DECAY1, None),
    "decay2": ModelNeeds("decay2", DECAY2, None),
}


def bundled_vessels() -> tuple[str, ...]:
    """Names of the bundled reference vessels (``src/diffship/vessels/*.json``)."""
    return tuple(sorted(p.stem for p in _VESSELS.glob("*.json")))


def missing_particulars(needs: Mapping[str, str], fixed: Iterable[str] = (), freed: Iterable[str] = ()) -> tuple[str, ...]:
    """The particulars (parameter names) that neither ``--fix`` nor ``--free`` sets, without a vessel."""
    given = set(fixed) | set(freed)
    return tuple(n for n in needs if n not in given)


def missing_message(model_name: str, needs: Mapping[str, str], reference_vessel: str | None,
                    missing: Iterable[str], vessel_name: str | None = None) -> str:
    """The one line that stops a fit whose particulars are missing: each missing parameter with the
    quantity that sets it, and how to give it."""
    what = "; ".join(f"{n} ({QUANTITIES[needs[n]]})" for n in missing)
    hint = ("give --vessel FILE (JSON, see src/diffship/vessels/*.json) or --fix NAME=VALUE for each"
            + (f", or --vessel {reference_vessel} for the model's reference vessel" if reference_vessel else ""))
    src = f"vessel {vessel_name} lacks" if vessel_name is not None else "no vessel given:"
    return f"model {model_name} needs the vessel's particulars; {src} {what}; {hint}"
