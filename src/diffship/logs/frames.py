"""Axis conventions of log sources and their conversion to diffship's NED / FRD axes.

diffship: earth axes North-East-Down (``x0`` north, ``y0`` east, ``z0`` down), body axes
Forward-Right-Down (``u`` forward, ``v`` to starboard, ``w`` down), heading ``psi`` clockwise from
north seen from above, rates ``p, q, r`` about the FRD axes.

ROS (REP 103): earth axes East-North-Up, body axes Forward-Left-Up, yaw counter-clockwise from east.

Vectors
    earth (ENU → NED):  ``(x_N, y_E, z_D) = (y_ENU, x_ENU, −z_ENU)``
    body  (FLU → FRD):  ``(x_F, y_R, z_D) = (x_FLU, −y_FLU, −z_FLU)`` — velocities, rates, forces, moments.

Attitude
    A quaternion ``q`` (rotation body → earth) gives the rotation matrix ``R(q)``. In ROS axes
    ``R_ned_frd = T · R_enu_flu(q) · F`` with ``T`` the ENU↔NED swap ``[[0,1,0],[1,0,0],[0,0,−1]]`` and
    ``F = diag(1, −1, −1)`` (FRD↔FLU). The Euler angles are the ZYX (yaw-pitch-roll) angles of
    ``R_ned_frd``: ``ψ = atan2(R₁₀, R₀₀)``, ``θ = −asin(R₂₀)``, ``φ = atan2(R₂₁, R₂₂)``. For a pure
    yaw this is ``ψ = π/2 − yaw_ROS`` (clockwise from north vs counter-clockwise from east).
    Reference: REP 103 "Standard Units of Measure and Coordinate Conventions"; Fossen (2011),
    *Handbook of Marine Craft Hydrodynamics and Motion Control*, §2.2 (Euler angles from a quaternion).

Plain NumPy; no JAX.
"""

from __future__ import annotations

import numpy as np
from jaxtyping import Float

from ..errors import DataError

__all__ = ["ANGLE_FROM_ATTITUDE", "FRAMES", "ROS_VECTOR_RULES", "euler_from_quaternion", "ros_vector_component",
           "rotation_from_quaternion"]

FRAMES = ("ros", "ned")

#: ROS (ENU/FLU) → diffship (NED/FRD): channel -> (ROS vector component, sign).
ROS_VECTOR_RULES: dict[str, tuple[str, float]] = {
    "x0": ("y", 1.0), "y0": ("x", 1.0), "z0": ("z", -1.0),  # earth: ENU -> NED
    "u": ("x", 1.0), "v": ("y", -1.0), "w": ("z", -1.0),  # body velocities: FLU -> FRD
    "p": ("x", 1.0), "q": ("y", -1.0), "r": ("z", -1.0),  # body rates
    "tau_x": ("x", 1.0), "tau_y": ("y", -1.0), "tau_z": ("z", -1.0),  # force (tau_z: yaw moment in 3 DOF)
    "tau_k": ("x", 1.0), "tau_m": ("y", -1.0), "tau_n": ("z", -1.0),  # moments
}
#: Channels taken from an attitude quaternion: channel -> index into (phi, theta, psi).
ANGLE_FROM_ATTITUDE = {"phi": 0, "theta": 1, "psi": 2}

_ENU_TO_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
_FLU_TO_FRD = np.diag([1.0, -1.0, -1.0])


def ros_vector_component(channel: str, xyz: Float[np.ndarray, "n 3"], where: str) -> Float[np.ndarray, " n"]:
    """The diffship ``channel`` from a ROS ENU/FLU vector ``xyz`` (columns x, y, z)."""
    if channel not in ROS_VECTOR_RULES:
        raise DataError(f"{where}: channel '{channel}' has no ROS (REP 103) vector rule; known: "
                        f"{sorted(ROS_VECTOR_RULES)}; use frame = \"ned\" with explicit scale for other channels.")
    comp, sign = ROS_VECTOR_RULES[channel]
    return sign * xyz[:, "xyz".index(comp)]


def rotation_from_quaternion(w: Float[np.ndarray, " n"], x: Float[np.ndarray, " n"], y: Float[np.ndarray, " n"],
                             z: Float[np.ndarray, " n"], where: str) -> Float[np.ndarray, "n 3 3"]:
    """Rotation matrices (body → earth) of unit quaternions ``w + xi + yj + zk`` (normalised here;
    a norm far from 1 is an error: the field is probably not a quaternion)."""
    q = np.stack([w, x, y, z], axis=1).astype(np.float64)
    norm = np.linalg.norm(q, axis=1)
    if np.any(~np.isfinite(norm)) or np.any(np.abs(norm - 1.0) > 0.05):
        i = int(np.argmax(~np.isfinite(norm) | (np.abs(norm - 1.0) > 0.05)))
        raise DataError(f"{where}: quaternion norm {norm[i]:.4g} at sample {i} (expected 1); check the field "
                        "and the component order (quaternion = \"wxyz\" or \"xyzw\").")
    w, x, y, z = (q / norm[:, None]).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1),
    ], axis=1)


def euler_from_quaternion(wxyz: Float[np.ndarray, "n 4"], frame: str, where: str) -> Float[np.ndarray, "n 3"]:
    """ZYX Euler angles ``(φ, θ, ψ)`` [rad] in NED/FRD of body → earth quaternions given in ``frame``
    (``"ros"``: ENU/FLU; ``"ned"``: already NED/FRD). ``ψ`` is unwrapped (continuous)."""
    R = rotation_from_quaternion(*wxyz.T, where=where)
    if frame == "ros":
        R = _ENU_TO_NED @ R @ _FLU_TO_FRD
    phi = np.arctan2(R[:, 2, 1], R[:, 2, 2])
    theta = -np.arcsin(np.clip(R[:, 2, 0], -1.0, 1.0))
    psi = np.unwrap(np.arctan2(R[:, 1, 0], R[:, 0, 0]))
    return np.stack([phi, theta, psi], axis=1)
