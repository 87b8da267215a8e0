"""DAQP in one place.

* :mod:`wbc.solvers.daqp.abi` -- DAQP's C structures and entry points as wbc calls them;
* :mod:`wbc.solvers.daqp.native` -- one DAQP workspace on one QP's buffers, solved by compiled code;
* :mod:`wbc.solvers.daqp.probe` -- the check that the layouts hold on the installed build;
* :mod:`wbc.solvers.daqp.backend` -- :class:`~wbc.solvers.daqp.backend.DaqpBackend`, the backend.
"""
