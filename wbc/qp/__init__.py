"""The control QP: its buffers and how the tick's items fill them.

* :mod:`wbc.qp.problem` -- :class:`~wbc.qp.problem.QP`, the preallocated buffers of one QP;
* :mod:`wbc.qp.layout` -- where each task's and constraint's rows sit in them;
* :mod:`wbc.qp.bounds` -- the variable bounds folded from the constraints' rows;
* :mod:`wbc.qp.reduction` -- the QP over a subset of the inputs (the others held);
* :mod:`wbc.qp.lifting` -- the lifted form at high DOF (dense task rows as variables).

It imports the core, the runtime, the model and the items (tasks, constraints).
"""
