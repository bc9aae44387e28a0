"""Channel names diffship knows and their units inside diffship (SI, radians). Plain Python, no JAX.

``--columns NAME=COLUMN`` maps a file's column to one of these names; files in degrees say so with
``--degrees COLUMN`` (:mod:`diffship.data` converts them). Kept free of numerical imports so that the
command line (:mod:`diffship.fit.args`) can list them without loading JAX.
"""

__all__ = ["CHANNEL_NAMES"]

#: Channel names diffship knows (``--columns NAME=COLUMN`` maps a file's column to one) and their
#: units inside diffship (files in degrees: ``--degrees COLUMN``).
CHANNEL_NAMES: dict[str, str] = {
    "time": "s", "x0": "m, north/ahead", "y0": "m, east/starboard", "psi": "rad, clockwise", "u": "m/s",
    "v": "m/s, starboard", "r": "rad/s, clockwise", "delta": "rad, starboard-positive after --rudder-sign",
    "n": "rev/s, propeller", "tau_x": "N", "tau_y": "N", "tau_z": "N m", "delta_n": "rad, water-jet nozzle",
    "rpm": "rev/min, water jets", "z0": "m", "phi": "rad", "theta": "rad", "w": "m/s", "p": "rad/s", "q": "rad/s",
}
