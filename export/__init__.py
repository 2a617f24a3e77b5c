"""Exporters of a design: URDF, MJCF, STL, bill of materials, design record.

Importing the package does nothing else: the shipped ontology's body plans (for a bundle
written before design records kept their own) are installed by the entry points
(``synth.reasoning.plans.install``: ``parmor``'s ``main``, the ROS worker, the block server's
runs).
"""
