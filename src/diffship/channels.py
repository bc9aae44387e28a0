"""Channel names diffship knows and their units inside diffship (SI, radians). Plain Python, no JAX.

``--columns NAME=COLUMN`` maps a file's column to one of these names; files in degrees say so with
``--degrees COLUMN`` (:mod:`diffship.data` converts them). Kept free of numerical imports so that the
command line (:mod:`diffship.fit.args`) can list them without loading JAX. The loader's checks of a file's
column names (:func:`check_header`, :func:`check_near_misses`) live here too.
"""

from collections.abc import Collection, Iterable, Sequence

from .errors import DataError

__all__ = ["CHANNEL_NAMES", "check_header", "check_near_misses"]

#: Channel names diffship knows (``--columns NAME=COLUMN`` maps a file's column to one) and their
#: units inside diffship (files in degrees: ``--degrees COLUMN``).
CHANNEL_NAMES: dict[str, str] = {
    "time": "s", "x0": "m, north/ahead", "y0": "m, east/starboard", "psi": "rad, clockwise", "u": "m/s",
    "v": "m/s, starboard", "r": "rad/s, clockwise", "delta": "rad, starboard-positive after --rudder-sign",
    "n": "rev/s, propeller", "tau_x": "N", "tau_y": "N", "tau_z": "N m", "delta_n": "rad, water-jet nozzle",
    "rpm": "rev/min, water jets", "z0": "m", "phi": "rad", "theta": "rad", "w": "m/s", "p": "rad/s", "q": "rad/s",
}


def check_header(where: str, names: Sequence[str]) -> None:
    """Stop at a column name that a file's header repeats (compared without surrounding spaces).

    Readers keep such columns apart by renaming the copies (pandas: ``psi``, ``psi.1``), so the run would
    silently use one of them; ``names`` is the raw header, before any reader renames it.
    """
    at: dict[str, list[int]] = {}
    for i, c in enumerate(names, 1):
        if str(c).strip():  # unnamed columns (a trailing separator) are not names
            at.setdefault(str(c).strip(), []).append(i)
    dup = {c: cols for c, cols in at.items() if len(cols) > 1}
    if dup:
        c, cols = next(iter(dup.items()))
        more = f" (also repeated: {', '.join(repr(d) for d in list(dup)[1:])})" if len(dup) > 1 else ""
        raise DataError(f"{where}: column '{c}' appears {len(cols)} times in the header (columns "
                        f"{', '.join(map(str, cols[:-1]))} and {cols[-1]}){more}; rename or drop all but one of them.")


def check_near_misses(where: str, unread: Iterable[str], present: Collection[str]) -> None:
    """Stop at a column kept under its own name whose name, case-folded and stripped, is a channel of
    :data:`CHANNEL_NAMES` that the run lacks (``Psi`` or ``PSI`` where there is no ``psi``): the run would
    load without that channel and the fit would leave it out without a word.

    ``unread``: the columns no channel is mapped to; ``present``: the channel names the run will have. A single
    capital letter is left alone: in ship notation ``U``, ``N``, ``R``, ``X``, ``Y`` name other quantities
    (total speed, yaw moment, resistance, forces) than the channels ``u``, ``n``, ``r``.
    """
    for col in unread:
        name = str(col).strip().casefold()
        if col in CHANNEL_NAMES or name not in CHANNEL_NAMES or name in present or (len(col) == 1 and col.isupper()):
            continue
        raise DataError(f"{where}: column '{col}' is not read as a channel; did you mean '{name}'? Rename it or "
                        f"map it: columns={{'{name}': '{col}'}} (CLI: --columns {name}={col}).")
