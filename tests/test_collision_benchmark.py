"""benchmarks/collision.py runs (no timing is asserted): wbc and mink on the same obstacle scene."""

import mujoco
import numpy as np

from benchmarks import collision


def test_the_mink_scene_holds_the_same_obstacles():
    shapes = collision.obstacles()
    model = collision.mink_model(shapes)
    for k, shape in enumerate(shapes):
        geom = model.geom(f"obstacle{k}")
        np.testing.assert_allclose(geom.pos, shape.pose[:3, 3])
        expected = [shape.radius] if geom.type[0] == mujoco.mjtGeom.mjGEOM_SPHERE else shape.size / 2
        np.testing.assert_allclose(geom.size[:len(expected)], expected)


def test_the_benchmark_runs(capsys):
    assert collision.main(["--repeats", "2", "--ticks", "20", "--warmup", "5", "--mink"]) == 0
    out = capsys.readouterr().out
    assert "median ratio collision / today" in out and "median ratio mink collision / mink" in out
    assert "median ratio mink collision / wbc collision" in out


def test_the_reference_comparison_runs_each_side_in_its_own_process(capsys):
    """``--reference``: this checkout as its own reference (its plain tick in a fresh process)."""
    assert collision.main(["--repeats", "1", "--ticks", "20", "--warmup", "5", "--reference",
                           str(collision.ROOT)]) == 0
    out = capsys.readouterr().out
    assert "plain" in out and "median ratio collision / " in out
    ratio = float(out.rsplit("(own processes and loops): ", 1)[1].split()[0])
    assert ratio > 0.0
