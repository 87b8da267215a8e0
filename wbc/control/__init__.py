"""The control loop: the controller and the pieces of its tick.

* :mod:`wbc.control.controller` -- :class:`~wbc.control.controller.Controller`, one QP per tick;
* :mod:`wbc.control.hierarchy` -- strict priorities (one QP per level);
* :mod:`wbc.control.fallback` -- the answer when the QP has none;
* :mod:`wbc.control.lm_damping` -- the damping that keeps the QP well posed near singularities;
* :mod:`wbc.control.diagnostics` -- what each tick did (:class:`~wbc.control.diagnostics.TickDiagnostics`).

It imports every layer below: core, runtime, model, the items, qp, solvers.
"""
