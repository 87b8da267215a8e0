"""Analysis of a robot's kinematics, outside the control loop.

* :mod:`wbc.analysis.singularity` -- singular configurations: tests, measures, lost directions,
  and the check of the certified conditions against the numeric rank;
* :mod:`wbc.analysis.singular_sets` -- the certified singular sets of the shipped robots (the
  robot-specific conditions, one function per robot, registered by model name);
* :mod:`wbc.analysis.scorbot_angles` -- the Scorbot-ER 4pc's DH and measured angle conventions.

It imports the core and the model only.
"""
