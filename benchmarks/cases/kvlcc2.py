"""Case ``kvlcc2`` (``kvlcc2_hsva_real`` in the CSV): the real HSVA KVLCC2 zigzags with the MMG model.

What is measured (full mode only; it takes minutes): ``diffship.studies.kvlcc2`` — MMG output
error on 4 training zigzags, prediction of the other 9 — whole-study wall time, compile/fit time,
convergence, the max and RMS first-overshoot error of the validation zigzags (closed loop and
open loop) and memory. Skipped with a message where ``../shared/data/kvlcc2_hsva`` is absent; in
quick mode it only records that the data were found. No equation-error baseline for MMG.
"""

from __future__ import annotations

import numpy as np

from benchmarks.common.fitapi import fit_numbers, kvlcc2_study
from benchmarks.record import maxrss_mb, say, timed


def run(rec, quick, figs=None):
    from diffship.data import shared_data_dir

    case = "kvlcc2_hsva_real"
    d = shared_data_dir()
    if d is None or not (d / "kvlcc2_hsva").is_dir():
        msg = "skipped: ../shared/data/kvlcc2_hsva not found (set DIFFSHIP_SHARED_DATA)"
        say(f"{case}: {msg}")
        rec.add(case, "-", "-", "skipped", 1.0, "", msg)
        return
    if quick:
        from diffship.data import kvlcc2_runs

        n = len(kvlcc2_runs())
        rec.add(case, "-", "-", "skipped", 1.0, "", f"data found ({n} runs); the MMG study runs in full mode only (minutes)")
        return
    try:
        import diffship.studies.kvlcc2  # noqa: F401
    except ImportError as exc:
        rec.add(case, "-", "-", "skipped", 1.0, "", f"diffship.studies.kvlcc2 not importable: {exc}")
        return
    say(f"{case}: MMG output error on 4 training zigzags, prediction of the other 9 (diffship.studies.kvlcc2)")
    st, wall = timed(kvlcc2_study)
    num = fit_numbers(st.fit)
    variant = "train=" + "+".join(st.train)
    rec.add(case, variant, "diffship_oe", "wall_s", wall, "s", "whole study: fit + 13 closed/open-loop predictions")
    rec.add(case, variant, "diffship_oe", "compile_s", num["compile_s"], "s")
    rec.add(case, variant, "diffship_oe", "fit_s", num["fit_s"], "s")
    rec.add(case, variant, "diffship_oe", "converged", num["converged"])
    rec.add(case, variant, "diffship_oe", "max_abs_err_overshoot1_validation_closed_loop", st.max_first_overshoot_error("cl"), "deg")
    rec.add(case, variant, "diffship_oe", "max_abs_err_overshoot1_validation_open_loop", st.max_first_overshoot_error("ol"), "deg")
    v = st.table[st.table.role == "validate"]
    rec.add(case, variant, "diffship_oe", "rms_err_overshoot1_validation_closed_loop",
            float(np.sqrt(np.mean(np.square(v.err_first_cl)))), "deg")
    rec.add(case, variant, "diffship_oe", "process_max_rss_mb", maxrss_mb(), "MB")
    rec.add(case, variant, "diffship_ee", "not_available", 1.0, "", "no equation-error baseline for the MMG model")


CASES = {"kvlcc2": run}
