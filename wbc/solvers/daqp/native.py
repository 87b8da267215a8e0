"""One DAQP workspace on one QP's buffers, solved by compiled code (no Python binding).

DAQP keeps pointers into the QP's own buffers (:class:`wbc.qp.problem.QP`: H, c, [G; A], upper,
lower), so a tick hands it nothing: :func:`wbc.runtime.kernels.native_qp.daqp_solve` re-forms the
factorisation (``daqp_update_ldp``), solves (``daqp_solve``), checks the answer against the
QP's bounds and rows (:func:`wbc.runtime.kernels.qp_defect`) and times itself -- as an op of the
tick program (:meth:`NativeWorkspace.add_op`, the whole tick one native call) or alone
(:meth:`NativeWorkspace.solve`).

**Warm start.** DAQP's constraint states (``sense``: active, lower, immutable) are the
warm start. With ``warm_start`` the problem's ``sense`` pointer is the workspace's own
array, so each tick starts from the previous working set; without it, it is a fresh copy
of the initial states (equality rows active), so each tick starts cold.

**A first try without DAQP.** On a QP without equality rows, when DAQP's working set holds no
active constraint (the last answer met no limit: always, without warm start), the compiled
solve first tries ``x = -H^-1 c`` (one Cholesky factorisation): when it satisfies every bound
and row exactly it is the QP's answer (H is positive definite: a feasible unconstrained
minimiser is the constrained one), with multipliers 0 and 0 iterations, and DAQP is not called
(its working set stays empty). A tick where no limit is active (most ticks of a tracking task)
then costs a factorisation instead of DAQP's update and solve.

A workspace made with ``working_set_first`` (the lower levels of strict priorities, whose band
rows are active tick after tick) tries the last working set instead: the minimiser with those
constraints held as equalities (a null-space method on one LU factorisation of the active rows:
:func:`wbc.runtime.kernels.native_qp._working_set_answer`) is the QP's answer when it meets
every optimality condition -- the other bounds and rows hold (relative defect at most the
workspace's ``primal_tol``, DAQP's own tolerance: 1e-6 in the levels) and each multiplier has
the sign of its side -- and DAQP is then not called (0 iterations, its working set unchanged);
with no active constraint it is the unconstrained minimiser as above. Otherwise DAQP solves, from that
working set. A workspace starts from the initial states (equality rows active).

**Memory.** The C structures live in float64 arrays this object owns (and a tick program
that runs the op keeps alive); DAQP's own allocations are freed when the object is
collected (``weakref.finalize``) and re-made by :meth:`NativeWorkspace.reset`.
"""

from __future__ import annotations

import ctypes
import weakref
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...qp.problem import QP
from ...runtime import kernels
from ...runtime.kernels import DAQP_CONTROL_ITERATIONS, DAQP_CONTROL_MASK, DAQP_CONTROL_OUTCOME, DAQP_CONTROL_SIZE
from ...runtime.program import TickProgram
from . import abi as daqp_abi
from .abi import Library, Problem, Result, Settings, Workspace, struct_in, words


class NativeWorkspace:
    """DAQP set up once on ``qp``'s buffers (see the module docstring).

    Args:
        library: the checked C entry points (:func:`wbc.solvers.daqp.probe.native`).
        qp: the QP whose buffers DAQP reads every tick.
        settings: DAQP settings (keys of :class:`wbc.solvers.daqp.abi.Settings`), validated upstream.
        warm_start: keep the working set from one tick to the next.
        working_set_first: try the last working set before DAQP (see the module docstring; its
            compiled solve costs ~1 s more CPU to compile after an install, so only where it pays:
            the lower levels of strict priorities).
    """

    def __init__(self, library: Library, qp: QP, settings: dict[str, Any], warm_start: bool,
                 working_set_first: bool = False) -> None:
        self.qp, self.warm_start, self.working_set_first = qp, warm_start, working_set_first
        self._library = library
        n, m = qp.n, qp.n + qp.n_ineq + qp.n_eq
        self.x = np.zeros(n)  #: DAQP's answer of the latest solve
        self.lam = np.zeros(m)  #: its multipliers (bounds, then rows)
        # scratch of the first try: H's Cholesky factor (then, trying the working set, the rest: kernels.native_qp)
        self._scratch = np.zeros((4 * n + 7 if working_set_first else n, n))
        self._op = kernels.DAQP_SOLVE_WORKING_SET if working_set_first else kernels.DAQP_SOLVE
        self.control = np.zeros(DAQP_CONTROL_SIZE)  #: mask in; exit flag, defect, time [s], iterations out
        self.control_view = self.control.data  #: the same memory (a memoryview), read item by item as Python floats
        # the initial constraint states (equality rows active), what a cold tick re-reads;
        # DAQP only reads the problem's sense (it copies it into the workspace's own)
        self._initial_sense = np.zeros(m, dtype=np.intc)
        self._initial_sense[qp.n + qp.n_ineq:] = daqp_abi.SENSE_EQUALITY
        # the C structures, in memory this object owns
        self.problem_words, self.work_words = np.zeros(words(Problem)), np.zeros(words(Workspace))
        self.result_words, self.settings_words = np.zeros(words(Result)), np.zeros(words(Settings))
        self.problem: Problem = struct_in(self.problem_words, Problem)
        self.work: Workspace = struct_in(self.work_words, Workspace)
        self.result: Result = struct_in(self.result_words, Result)
        self.settings: Settings = struct_in(self.settings_words, Settings)
        library.lib.daqp_default_settings(ctypes.addressof(self.settings))
        for key, value in settings.items():
            setattr(self.settings, key, value)
        self.result.x, self.result.lam = self.x.ctypes.data, self.lam.ctypes.data if m else None
        # neutral data for setup_daqp (H = I, no rows, loose bounds): setup only allocates;
        # the first tick re-forms everything from the QP's buffers (a cold update)
        self._neutral_H, self._neutral_f = np.eye(n), np.zeros(n)
        self._neutral_A = np.zeros((max(m - n, 1), n))
        self._neutral_upper = np.ones(m)
        self._neutral_upper[qp.n + qp.n_ineq:] = 0.0
        self._neutral_lower = -self._neutral_upper
        self._finalizer = weakref.finalize(self, _free, library.lib, self.work)
        self._program = TickProgram()  # the solve alone, for solve()
        self._program.add(self._op, **self.operands())
        self._neutral_solve = TickProgram()  # DAQP's solve alone (never the minimiser), for reset()
        self._neutral_solve.add(kernels.DAQP_SOLVE, **self._shared_operands(), factor=self._scratch[:n],
                                unconstrained_first=0)
        self.reset()

    def reset(self) -> None:
        """Free DAQP's memory and set it up again: the next solve starts cold."""
        _free(self._library.lib, self.work)
        self.work_words.fill(0.0)
        self.work.settings = ctypes.addressof(self.settings)
        problem, qp = self.problem, self.qp
        problem.n, problem.m, problem.ms = qp.n, qp.n + qp.n_ineq + qp.n_eq, qp.n
        problem.break_points, problem.nh, problem.problem_type = None, 0, 0
        self._point(self._neutral_H, self._neutral_f, self._neutral_A, self._neutral_upper, self._neutral_lower)
        problem.sense = self._initial_sense.ctypes.data
        flag = self._library.lib.setup_daqp(ctypes.addressof(problem), ctypes.addressof(self.work), None)
        if flag < 0:  # cannot happen on the neutral problem; never run on a half-made workspace
            raise RuntimeError(f"DAQP could not set up a {qp.n}-variable workspace (exit flag {flag})")
        # one solve of the neutral problem: DAQP's memory is touched now, not in the first tick
        self.control[DAQP_CONTROL_MASK] = daqp_abi.COLD_UPDATE
        self._neutral_solve.run(0.0)
        self._point(qp.H, qp.c, qp.C, qp.upper, qp.lower)
        if self.warm_start:  # the working set carries over from tick to tick, from the initial states
            self._sense()[:] = self._initial_sense  # (not what the neutral solve left)
            problem.sense = self.work.sense
        self.control[DAQP_CONTROL_MASK] = daqp_abi.COLD_UPDATE

    def _point(self, H: np.ndarray, f: np.ndarray, A: np.ndarray, upper: np.ndarray, lower: np.ndarray) -> None:
        problem = self.problem
        problem.H, problem.f, problem.bupper, problem.blower = (H.ctypes.data, f.ctypes.data, upper.ctypes.data,
                                                                lower.ctypes.data)
        problem.A = A.ctypes.data if A.size else None

    def operands(self) -> dict[str, Any]:
        """The operands of the compiled solve (the declaration of
        `wbc.runtime.kernels.native_qp.DAQP_SOLVE`, or ``DAQP_SOLVE_WORKING_SET`` with ``working_set_first``)."""
        if self.working_set_first:  # (settings: the try takes DAQP's primal_tol)
            return {**self._shared_operands(), "scratch": self._scratch, "settings": self.settings_words}
        return {**self._shared_operands(), "factor": self._scratch, "unconstrained_first": int(self.qp.n_eq == 0)}

    def _shared_operands(self) -> dict[str, Any]:
        entry = self._library.entry
        return dict(problem=self.problem_words, workspace=self.work_words, result=self.result_words,
                    control=self.control, data=self.qp.data, x=self.x, lam=self.lam, n=self.qp.n,
                    size=self.qp.data.size, m=self.lam.size, update_ldp=entry.update_ldp, solve=entry.solve,
                    clock_gettime=entry.clock_gettime, clock_id=entry.clock_id, steady_mask=daqp_abi.WARM_UPDATE,
                    sense_word=Problem.sense.offset // 8)

    def add_op(self, program: TickProgram) -> None:
        """Append the solve to ``program``: it runs after the program's NaN screen, and only
        when that found none (exit flag ``kernels.DAQP_SKIPPED``)."""
        program.add(self._op, **self.operands())
        program.keep_alive(self)

    @property
    def clock(self) -> tuple[int, int]:
        """(address of libc's ``clock_gettime``, clock id): the clock the compiled solve is timed with
        (that of ``time.perf_counter``), for :meth:`wbc.runtime.program.TickProgram.set_clock`."""
        entry = self._library.entry
        return entry.clock_gettime, entry.clock_id

    def add_accept_op(self, program: TickProgram, tolerance: NDArray[np.float64],
                      levels_above: Sequence[NativeWorkspace] = ()) -> None:
        """Append the check of this workspace's latest solve to ``program`` (after :meth:`add_op`):
        the program's flag ``FLAG_ACCEPTED`` (its run returns ``RUN_ACCEPTED``) when DAQP solved
        and the answer's defect is at most ``tolerance[0]``; the solve time is then kept in
        ``control[DAQP_CONTROL_ACCEPTED_TIME]``, with the solve times of the workspaces
        ``levels_above`` added (strict priorities: this is the last level's)."""
        program.add(kernels.DAQP_ACCEPT, control=self.control, tolerance=tolerance)
        for upper in levels_above:
            program.add(kernels.DAQP_ACCEPT_LEVEL, control=self.control, upper=upper.control)

    def solve(self) -> tuple[int, float, float]:
        """Solve now (one compiled call): (exit flag, answer defect, solve time [s])."""
        self._program.run(0.0)
        return self.outcome()

    def outcome(self) -> tuple[int, float, float]:
        """(exit flag, answer defect, solve time [s]) of the latest compiled solve."""
        exitflag, defect, elapsed = self.control[DAQP_CONTROL_OUTCOME].tolist()
        return int(exitflag), defect, elapsed

    @property
    def working_set(self) -> NDArray[np.intc]:
        """DAQP's constraint states (active, at the lower side, immutable): the warm start of the
        next solve, as a copy. Assigning the states of another workspace on a QP of the same
        shape makes this one's next solve start where that one's would (a warm-started
        workspace only: a cold one starts from the initial states every solve)."""
        return self._sense().copy()

    @working_set.setter
    def working_set(self, states: NDArray[np.intc]) -> None:
        if self.warm_start:
            self._sense()[:] = states

    def _sense(self) -> NDArray[np.intc]:
        """The workspace's own constraint states (DAQP's memory)."""
        address = self.work.sense
        assert address, "DAQP workspace not set up"
        return np.ctypeslib.as_array((ctypes.c_int * self.problem.m).from_address(address))

    @property
    def iterations(self) -> int:
        """DAQP's iterations in the latest solve."""
        return int(self.control[DAQP_CONTROL_ITERATIONS])


def _free(lib: ctypes.CDLL, work: Workspace) -> None:
    """Free what DAQP allocated in ``work`` (not the settings: they are wbc's)."""
    if work.sense or work.lam:
        settings, work.settings = work.settings, None
        lib.free_daqp_workspace(ctypes.addressof(work))
        lib.free_daqp_ldp(ctypes.addressof(work))
        work.settings = settings
