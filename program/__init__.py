"""The programming layer: programs of behaviour calls, ROS services and block pages."""

# a bundle written before design records kept their body plan is rebuilt from the shipped
# ontology's (synth.bodyplan.install: cheap, the ontology is read only when asked)
import synth.bodyplan  # noqa: E402, F401
