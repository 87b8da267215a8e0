"""The application: scenario files, closed-loop runs and what shows them.

* :mod:`wbc.app.scenario` -- scenario files (robot, stack, reference, run) and their checks;
* :mod:`wbc.app.references` -- the reference motions a scenario's tasks follow;
* :mod:`wbc.app.closed_loop` -- a scenario run in closed loop (kinematic or simulated);
* :mod:`wbc.app.simulation` -- the MuJoCo simulation of a run (extra ``[sim]``);
* :mod:`wbc.app.plotting` -- the figures of runs (extra ``[plot]``);
* :mod:`wbc.app.view` -- the 3-D view of runs (extra ``[view]``);
* :mod:`wbc.app.outputs` -- the checked, atomic writing of output files;
* :mod:`wbc.app.cli` -- the ``wbc`` command.

The top layer: it may import every other one.
"""
