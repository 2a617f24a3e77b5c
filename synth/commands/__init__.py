"""The command line and the studies: ``parmor`` itself (:mod:`synth.commands.cli`), parameter
studies (:mod:`synth.commands.sweep`, local or on Ray through :mod:`synth.commands.backend`)
and regression suites of rule sets (:mod:`synth.commands.regress`). The top layer: it may
import every other package (docs/architecture.md)."""
