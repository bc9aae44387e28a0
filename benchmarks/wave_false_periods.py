"""Does the wave candidate appear where there is no wave?

For every scenario of the independent grid (``--quick``: strong, seed 1, one null per vessel;
otherwise weak + strong, seeds 1–2), the diagnosis is run with the wave as the **only** candidate:
without a periodic training residual (:func:`diffship.diagnose.periodic.training_period`) it
stops right after the base fit ("no candidate applies"); with one, the wave is refitted and judged
on the held-out runs. Reports per scenario whether a period was found and whether the wave alone
would be attributed — the exposure of the other effects' scenarios to a wrong wave attribution.

Usage::

    python -m benchmarks wave_false_periods --quick [--vessels usv] [--only TEXT]
"""

from __future__ import annotations

import argparse
import time

import diffship  # noqa: F401  (float64)
from diffship.data import Run
from diffship.diagnose import DiagnoseOptions, diagnose
from diffship.errors import DataError
from diffship.models import Fossen3, Nomoto1

from benchmarks import independent  # noqa: E402


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--vessels", default="ship,usv")
    p.add_argument("--only", default="")
    a = p.parse_args(argv)
    vessels = tuple(a.vessels.split(","))
    grid = (independent.scenarios(vessels, sizes=("strong",), seeds=(1,), nulls=1) if a.quick
            else independent.scenarios(vessels, sizes=("weak", "strong"), seeds=(1, 2), nulls=2))
    if a.only:
        grid = [s for s in grid if any(k in s.name for k in a.only.split(","))]
    n_found = n_attr = 0
    for sc in grid:
        g = independent.generate(sc)
        mk = lambda gs: [Run(x["name"], x["time"], x["channels"], {"source": "independent"}) for x in gs]  # noqa: E731
        base = Nomoto1() if sc.vessel == "ship" else Fossen3()
        t0 = time.perf_counter()
        try:
            d = diagnose(base, mk(g["train"]), mk(g["val"]), options=DiagnoseOptions(effects=("wave",)))
        except DataError:
            print(f"{sc.name:34s} no periodic training residual (wave no candidate)  {time.perf_counter() - t0:5.0f} s",
                  flush=True)
            continue
        n_found += 1
        w = next(r for r in d.ranking if r.effect == "wave")
        n_attr += bool(d.selected)
        print(f"{sc.name:34s} period {w.params.get('T_w', float('nan')):.3g} s; wave {w.verdict}; E {d.E_before:.3g} → "
              f"{d.E_after:.3g}, gain {100 * w.validation_gain:.1f} %  {time.perf_counter() - t0:5.0f} s", flush=True)
    print(f"{len(grid)} scenarios: a periodic training residual in {n_found}, the wave alone attributed in {n_attr}")
