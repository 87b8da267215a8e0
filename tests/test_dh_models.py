"""The shipped Scorbot-ER 4pc and PUMA 560 against their DH tables, written out in tests/dh_tables.py."""

import numpy as np
import pytest

import wbc
from dh_tables import PUMA, SCORBOT, dh_frames, puma_table, scorbot_table

DEG = np.pi / 180.0


@pytest.fixture(scope="module")
def scorbot() -> wbc.Robot:
    return wbc.load_robot("scorbot_er4pc")


@pytest.fixture(scope="module")
def puma() -> wbc.Robot:
    return wbc.load_robot("puma560")


def test_scorbot_is_a_fixed_5dof_arm_with_published_limits(scorbot):
    assert scorbot.nq == scorbot.nv == 5
    assert scorbot.base.kind is wbc.BaseKind.FIXED
    assert scorbot.end_effector == "ee"
    np.testing.assert_allclose(scorbot.lower, np.array([-155, -35, -130, -130, -180]) * DEG, atol=1e-12)
    np.testing.assert_allclose(scorbot.upper, np.array([155, 130, 130, 130, 180]) * DEG, atol=1e-12)


def test_puma_is_a_fixed_6dof_arm_with_corkes_limits(puma):
    assert puma.nq == puma.nv == 6
    assert puma.base.kind is wbc.BaseKind.FIXED
    np.testing.assert_allclose(puma.lower, np.array([-160, -45, -225, -110, -100, -266]) * DEG, atol=1e-12)
    np.testing.assert_allclose(puma.upper, np.array([160, 225, 45, 170, 100, 266]) * DEG, atol=1e-12)


def test_scorbot_ee_is_dh_frame_5_on_1000_configurations(scorbot, rng):
    for q in rng.uniform(scorbot.lower, scorbot.upper, size=(1000, 5)):
        np.testing.assert_allclose(scorbot.frame_pose(q, "ee"), dh_frames(scorbot_table(q))[-1], rtol=0, atol=1e-12)


def test_scorbot_stretched_forward_at_zero(scorbot):
    # theta = 0: upper arm and forearm horizontal, tool (theta4 offset pi/2 in the DH table) along them
    g = SCORBOT
    np.testing.assert_allclose(scorbot.frame_pose(np.zeros(5), "ee")[:3, 3],
                               [g["l1"] + g["l2"] + g["l3"] + g["d5"], 0.0, g["d1"]], atol=1e-12)


def test_puma_ee_is_dh_frame_6_and_wrist_center_is_origin_of_frame_4(puma, rng):
    for q in rng.uniform(puma.lower, puma.upper, size=(1000, 6)):
        frames = dh_frames(puma_table(q))
        np.testing.assert_allclose(puma.frame_pose(q, "ee"), frames[6], rtol=0, atol=1e-12)
        wrist = puma.frame_pose(q, "wrist_center")
        np.testing.assert_allclose(wrist[:3, 3], frames[4][:3, 3], rtol=0, atol=1e-12)
        np.testing.assert_allclose(wrist[:3, 2], frames[3][:3, 2], rtol=0, atol=1e-12)  # joint-4 axis


def test_puma_zero_pose_is_corkes_L_shape(puma):
    # Corke's qz: flange at (a2 + a3, -d3, d4)
    g = PUMA
    np.testing.assert_allclose(puma.frame_pose(np.zeros(6), "ee")[:3, 3], [g["a2"] + g["a3"], -g["d3"], g["d4"]],
                               atol=1e-12)


def test_geometry_sidecars_match_the_urdfs(scorbot, puma):
    assert scorbot.parameters["geometry"] == SCORBOT
    assert puma.parameters["geometry"] == PUMA
