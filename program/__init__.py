"""The programming layer: programs of behaviour calls, ROS services and block pages.

Importing the package does nothing else: the entry points (the ROS worker's ``main``, the
block server's runs) install the shipped ontology's body plans themselves
(``synth.reasoning.plans.install``).
"""
