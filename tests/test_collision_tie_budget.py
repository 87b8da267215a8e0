"""The tie rows' budget of wbc.CollisionAvoidance (``CORNER_ROWS``): when more capsule ends and
overhang points tie than the budget holds, exactly the budget's rows are written and every row
after them stays inert (``G = 0``, ``h = 1``): no live row outside the block the braking, the
labels and the count know of. youbot_obstacle's closed loop meets the budget on a few ticks."""

from pathlib import Path

import numpy as np

import wbc
from wbc.app.closed_loop import run
from wbc.app.scenario import load_scenario
from wbc.collision.avoidance import CORNER_ROWS
from wbc.constraints.constraint import ConstraintRows
from wbc.model.kinematics import Kinematics

#: a capsule of the youBot's arm lying nearly parallel to a thin box's face (tilted < 0.02 rad, 48 mm apart),
#: overhanging the face: its ends and the overhang points tie with the witness (more than a
#: budget of 3 holds; found by a random search on the code before the budget was checked first)
Q_PARALLEL = np.array([0.0, 0.0, 0.0, 0.25833317, 0.57728801, -0.37504551, 0.7681596, -1.03251362])
BOX_POSE = np.array([[0.52605052, -0.80192853, -0.28316334, 0.29079021],
                     [0.1343152, 0.40711776, -0.90344593, 0.11002257],
                     [0.8397799, 0.43722506, 0.3218757, 0.22240052],
                     [0.0, 0.0, 0.0, 1.0]])
BOX_SIZE = (0.1724173499610547, 0.1, 0.02)
SCENARIO = Path(__file__).resolve().parents[1] / "tasks" / "youbot_obstacle.toml"


def _rows(data, nv):
    n = data.n_inequalities
    rows = ConstraintRows(np.full(nv, -np.inf), np.full(nv, np.inf), np.zeros((n, nv)), np.zeros(n),
                          np.zeros((0, nv)), np.zeros(0))
    data.write_static(rows)  # (every row inert, as a controller's are when it is built)
    return rows


def test_a_spent_budget_writes_no_row_past_it():
    robot = wbc.load_robot("youbot")
    box = wbc.Box(BOX_POSE, BOX_SIZE)
    data = wbc.CollisionAvoidance([box], self_collision=False, capacity=3, detection_distance=0.078).bind(robot)
    rows = _rows(data, robot.nv)
    kin = Kinematics(robot)
    kin.update(Q_PARALLEL)
    data.compute(kin, 0.01, rows)
    count, corners = data.pairs.count, data.corners
    assert count < 3 and corners == 3  # room for a pair row left, the budget of ties spent
    end = count + corners
    np.testing.assert_array_equal(rows.G[end:], 0.0)  # before: a live tie row at count + 3
    np.testing.assert_array_equal(rows.h[end:], 1.0)
    assert data.row_labels()[end:] == [f"row {i} (no pair)" for i in range(end, data.n_inequalities)]


def test_rows_past_a_spent_tie_budget_stay_inert_in_a_closed_loop():
    scenario = load_scenario(SCENARIO)
    robot, dt = scenario.robot, scenario.dt
    avoidance = next(c for c in scenario.constraints if isinstance(c, wbc.CollisionAvoidance))
    data = avoidance.bind(robot)  # a second data of the same constraint, computed on the loop's q
    n, nv = data.n_inequalities, robot.nv
    rows = ConstraintRows(np.full(nv, -np.inf), np.full(nv, np.inf), np.zeros((n, nv)), np.zeros(n),
                          np.zeros((0, nv)), np.zeros(0))
    data.write_static(rows)
    kin = Kinematics(robot)
    spent = []

    def check(k, q):
        # (the rows are left as the last tick wrote them: the kernels rewrite those after this tick's only up to
        # the last tick's -- the rest must have stayed inert, which the check below sees tick after tick)
        kin.update(q)
        data.compute(kin, dt, rows)
        count, corners = data.pairs.count, data.corners
        assert corners <= CORNER_ROWS and count + corners <= n
        if corners == CORNER_ROWS:
            spent.append(k)
        end = count + corners
        assert np.all(rows.G[end:] == 0.0) and np.all(rows.h[end:] == 1.0), f"tick {k}: a live row past the tie rows"
        labels = data.row_labels()
        assert len(labels) == n and all("no pair" in label for label in labels[end:])

    run(scenario, on_tick=check)
    assert spent  # the loop met the budget (on 44 of its 600 ticks when written)
