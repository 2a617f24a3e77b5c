"""Kinematic tree models and dynamics (forward kinematics, RNEA); imports nothing of parmor."""
