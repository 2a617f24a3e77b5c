"""Verification: a sized design's behaviours simulated in MuJoCo, nominal and perturbed,
judged on what the robot did, and failures fed back into the sizing or the refusal.

The modules, in the order a design meets them:

- :mod:`.source`: the one bundle reader (a bundle on disk or in memory, read once);
- :mod:`.simulate`: one run of a plan on a MuJoCo model (the servo law, the rollout, the
  feedback loops wired to the sensors) and what it measured;
- :mod:`.verdict`: the criteria a run is judged by;
- :mod:`.perturb` (and ``perturb.toml``, its ranges): the variation a printed robot meets,
  drawn per seed and applied to the model, and the worst-looking first;
- :mod:`.runs`: the bundle's behaviours run nominally and under perturbations (the
  harness ``parmor simulate``, ``design`` and ``sweep`` share), and the one set-up of a
  perturbed run and of its replay with one cause changed;
- :mod:`.results`: what the runs found, typed, serialised once for ``design.json``;
- :mod:`.robust`: the perturbed runs of a design in the loop, and what K of K shows;
- :mod:`.causes`: the protocol of a cause of failed perturbed runs, and the causes:
  :mod:`.play`, :mod:`.wheels`, :mod:`.gains`, :mod:`.hold`;
- :mod:`.loop`: the strengthening loop: simulate, repair, size again, judge.

Nothing is imported here: ``parmor --help`` and a conceptual design stay import-light
(MuJoCo and the controllers are imported where a run needs them).
"""
