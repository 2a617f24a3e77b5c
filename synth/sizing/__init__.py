"""The structure generator: the sizing loop (:mod:`synth.sizing.structure`), each structure
family's sizing rules (:mod:`synth.sizing.families`), the behaviours' worst-case loads
(:mod:`synth.sizing.behaviour_loads`), the actuator assignment (:mod:`synth.sizing.assign`:
clingo) and the printed links (:mod:`synth.sizing.links`, a chain's as one convex program in
:mod:`synth.sizing.chain_links`). Below the bundle's exporters, above the conceptual step
(docs/architecture.md)."""
