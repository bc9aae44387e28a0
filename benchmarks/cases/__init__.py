"""The suite's cases: one module per case, each defining ``CASES = {name: run}`` with
``run(rec, quick, figs)``.

* :mod:`.nomoto` — ``nomoto`` (linear Nomoto truth: noise levels, seeds, sweeps, random starts,
  vmapped batches; :mod:`.nomoto_batch` holds its batched fits) and ``nomoto_cubic`` (cubic truth,
  model-structure error);
* :mod:`.fossen3` — ``fossen3`` (the 3-DOF USV; scipy on the identical problem);
* :mod:`.sspa` — ``sspa`` (real SSPA 20/20 zigzag);
* :mod:`.kvlcc2` — ``kvlcc2`` (real HSVA KVLCC2 zigzags, MMG study);
* :mod:`.vmm` — ``vmm`` (VMM ship, zigzags and turning circle);
* :mod:`.rov` — ``rov`` (6-DOF BlueROV2).

Add a case: drop a module here that defines ``CASES`` and add its name to :data:`MODULES`. Run
some cases alone with ``python -m benchmarks suite --cases NAME,...``.
"""

#: the case modules, in the order the full suite runs them
MODULES = ("nomoto", "fossen3", "sspa", "kvlcc2", "vmm", "rov")
