"""One module per benchmark case; each defines ``CASES = {name: run}`` with ``run(rec, quick, figs)``
and runs alone as ``python -m benchmarks.cases.<module> [--quick] [--out DIR]``.

* :mod:`.nomoto` — ``nomoto`` (linear Nomoto truth: noise levels, seeds, sweeps, random starts,
  vmapped batches) and ``nomoto_cubic`` (cubic truth, model-structure error);
* :mod:`.fossen3` — ``fossen3`` (the 3-DOF USV; scipy on the identical problem);
* :mod:`.vmm` — ``vmm`` (VMM ship, zigzags and turning circle);
* :mod:`.rov` — ``rov`` (6-DOF BlueROV2);
* :mod:`.sspa` — ``sspa`` (real SSPA 20/20 zigzag);
* :mod:`.kvlcc2` — ``kvlcc2`` (real HSVA KVLCC2 zigzags, MMG study).
"""
