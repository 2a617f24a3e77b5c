"""The conceptual step: the reasoner (:mod:`synth.reasoning.solver`: clingo over the
ontology's ASP translation), the paper's Procedure 1 (:mod:`synth.reasoning.conceptual`:
candidates, questions, conflicts), the robot types' body plans read from the ontology
(:mod:`synth.reasoning.plans`), types composed for a request
(:mod:`synth.reasoning.composition`), ``parmor explain`` and the grounding probe. Below the
structure generator (:mod:`synth.sizing`), above the controllers (docs/architecture.md)."""
