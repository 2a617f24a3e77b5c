"""Verification: a sized design's behaviours simulated in MuJoCo, nominal and perturbed,
judged on what the robot did, and failures fed back into the sizing or the refusal.

The modules, in the order a design meets them:

- :mod:`.simulate`: one run of a plan on a MuJoCo model (the servo law, the rollout, the
  feedback loops wired to the sensors) and what it measured;
- :mod:`.verdict`: the criteria a run is judged by;
- :mod:`.perturb` (and ``perturb.toml``, its ranges): the variation a printed robot meets,
  drawn per seed and applied to the model;
- :mod:`.runs`: the bundle's behaviours run nominally and under perturbations (the
  harness ``parmor simulate``, ``design`` and ``sweep`` share), and the replay of one
  perturbed run with one cause changed;
- :mod:`.robust`: the perturbed runs of a design in the loop, and what K of K shows;
- :mod:`.hold`, :mod:`.wheels` and the play (:mod:`.robust`): causes of a failed
  perturbed run, each measured by replays, and what answers it;
- :mod:`.loop`: the strengthening loop: simulate, repair, size again, judge.

Nothing is imported here: ``parmor --help`` and a conceptual design stay import-light
(MuJoCo and the controllers are imported where a run needs them).
"""
