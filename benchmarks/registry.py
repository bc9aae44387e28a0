"""Every benchmark, by name: ``python -m benchmarks NAME [ARGS]`` runs ``main(ARGS)`` of its module.

Add a benchmark: a module (or package) with ``main(argv) -> int`` that writes its result to
``benchmarks/results/NAME.md``, and one line below. Nothing here imports a benchmark: a module is
imported only when its name is run, so a benchmark's optional peers (CasADi, shipmmg, Dask) are
needed only by that benchmark.
"""

from __future__ import annotations

#: name → (module, what it measures)
BENCHMARKS: dict[str, tuple[str, str]] = {
    "suite": ("benchmarks.suite", "output error vs equation error vs scipy/NumPy peers on six cases: accuracy, "
              "speed at equal cost, batches (report.md, all_numbers.csv)"),
    "timing": ("benchmarks.timing", "diffship vs CasADi on one fossen3 fit: cold process, one fit, batches "
               "(modes cold, single, batched; timing_<mode>.md)"),
    "compile_time": ("benchmarks.compile_time", "cold and cached python -m diffship.fit process of every model"),
    "compile_options": ("benchmarks.compile_options", "XLA optimisation level of diffship's CPU programs"),
    "integrators_speed": ("benchmarks.integrators_speed", "diffship's integrators on the fossen3 fit"),
    "simulate_speed": ("benchmarks.simulate_speed", "simulation and Jacobian cost: RK4 scan vs diffrax Tsit5 "
                       "(prints)"),
    "fossen3_speed": ("benchmarks.fossen3_speed", "fossen3 3 × 300 s: diffship vs scipy at equal final cost"),
    "fossen3_coverage": ("benchmarks.fossen3_coverage", "standard-error coverage of the fossen3 fit over seeds"),
    "fossen3_crlb": ("benchmarks.fossen3_crlb", "Cramér–Rao bound of the fossen3 USV truth's coefficients: data limit "
                     "vs the fit's spread"),
    "at_sea_hakusan": ("benchmarks.at_sea_hakusan", "a real ship at sea under autopilot (HAKUSAN, 1 Hz; --data "
                       "HAKUSAN.txt.gz): output error, prediction error, k-step-ahead predictions"),
    "at_sea_synthetic": ("benchmarks.at_sea_synthetic", "autopilot in narrow-band waves: output error against "
                         "prediction error (OU, wave), the closed-loop test"),
    "lm_stop": ("benchmarks.lm_stop", "cost of the LM stopping rule on ordinary fits"),
    "coverage": ("benchmarks.coverage", "coverage of 95 % intervals with noisy inputs and outputs"),
    "coverage_metrics": ("benchmarks.coverage_metrics", "coverage of 95 % intervals of predicted manoeuvre metrics"),
    "bootstrap_coverage": ("benchmarks.bootstrap_coverage", "coverage of bootstrap 95 % intervals over seeds"),
    "ee_cutoff": ("benchmarks.ee_cutoff", "equation error on the 6-DOF ROV: automatic vs fixed cut-off"),
    "estimators": ("benchmarks.estimators", "OE, multiple shooting, PEM and EE under coloured disturbances"),
    "estimators_hsva": ("benchmarks.estimators_hsva", "the estimators on the real HSVA KVLCC2 zigzags"),
    "kvlcc2_second_minimum": ("benchmarks.kvlcc2_second_minimum", "a KVLCC2 fit point: early stop or second "
                              "minimum (prints)"),
    "kvlcc2_rudder_offset": ("benchmarks.kvlcc2_rudder_offset", "the rudder offset each HSVA zigzag asks of a "
                             "fitted MMG (its asymmetry, run by run)"),
    "shipmmg_peer": ("benchmarks.shipmmg_peer", "diffship's MMG fitted on another MMG implementation's zigzags"),
    "fleet": ("benchmarks.fleet", "python -m diffship.fleet vs a shell loop of python -m diffship.fit"),
    "diagnose_current_case": ("benchmarks.diagnose_current_case", "the whole diagnosis of a USV in a current"),
    "diagnose_kvlcc2": ("benchmarks.diagnose_kvlcc2", "gap diagnosis of the MMG on the real KVLCC2 zigzags"),
    "diagnosis_independent": ("benchmarks.diagnosis_independent", "the diagnosis on hidden effects from an "
                              "independent NumPy generator (74 scenarios)"),
    "withheld_effects": ("benchmarks.withheld_effects", "the diagnosis on data whose effect the model lacks"),
    "withheld_real": ("benchmarks.withheld_real", "the diagnosis on real KVLCC2 logs with injected effects"),
    "drift_truth": ("benchmarks.drift_truth", "real KVLCC2 logs with an injected drift: the true current against a "
                    "force fixed to the hull, by the fit's likelihood"),
    "wave_family": ("benchmarks.wave_family", "the wave effect on the generator's wave scenarios"),
    "wave_false_periods": ("benchmarks.wave_false_periods", "does a wave candidate appear without waves (prints)"),
    "discover": ("benchmarks.discover", "structure discovery on a USV with withheld terms"),
    "discover_independent": ("benchmarks.discover_independent", "structure discovery on independent USV truths "
                             "with extra terms (5 + null), beside SINDy and FROLS peers"),
    "robustness": ("benchmarks.robustness", "one fit, one answer: cases × variants (rate, initial-state rule, starts, "
                   "warm-up, integrator) on one fixed scale (robustness[_quick].md)"),
}
