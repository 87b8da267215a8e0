"""A read-only install -- the package folder and HOME not writable, ``NUMBA_CACHE_DIR`` unset,
the usual setup of a service, a container or a system-wide install -- works: numba has nowhere
to cache the kernels, so they compile in memory, said once on stderr naming the fix
(``NUMBA_CACHE_DIR``), and ``wbc run`` and a controller command as usual.

The sandbox is a private mount namespace (``unshare -m``, or ``unshare -rm`` as an unprivileged
user) in which the package folder and a fresh HOME are bind-mounted read-only; the mounts do
not leave the namespace. Where it cannot be set up the test skips, unless
``WBC_REQUIRE_SANDBOX=1`` (CI sets it), which turns that into a failure.
"""

from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import wbc
from conftest import NEUTRAL, TASKS
from wbc.runtime.kernels import _cache

PACKAGE = Path(wbc.__file__).resolve().parent
READY = "wbc-test: read-only sandbox ready"
Q = [0.1, -0.2, 0.3, 0.2, 0.4, -0.8, 0.6, 0.1]
PROGRAM = f"""
    import json, sys
    import numpy as np
    import wbc
    from wbc.cli import main

    status = main(["run", {str(TASKS / "youbot_reach.toml")!r}, "--json", "--no-progress", "--duration", "0.05"])
    robot = wbc.load_robot("youbot")
    controller = wbc.Controller(robot, [wbc.PostureTask(1.0, gain=0.5)], [wbc.JointVelocityLimits()])
    print(json.dumps(controller.step(np.array({Q!r})).tolist()))
    sys.exit(status)
"""


def _in_read_only_sandbox(code: str, read_only: list[Path], env: dict[str, str]) -> subprocess.CompletedProcess:
    """``python -c code`` with the folders ``read_only`` bind-mounted read-only in a private
    mount namespace; skips (fails under WBC_REQUIRE_SANDBOX) when no namespace can be made."""
    mounts = " && ".join(f"mount --bind {p} {p} && mount -o remount,bind,ro {p}"
                         for p in map(shlex.quote, map(str, read_only)))
    probes = " && ".join(f"! touch {shlex.quote(str(p / '.wbc-write-probe'))} 2>/dev/null" for p in read_only)
    script = f'{mounts} && {probes} && echo "{READY}" >&2 && exec "$0" -c "$1"'
    attempts = []
    for unshare in (["unshare", "-m"], ["unshare", "-rm"]):
        try:
            result = subprocess.run([*unshare, "sh", "-c", script, sys.executable, textwrap.dedent(code)],
                                    capture_output=True, text=True, env=env, cwd=NEUTRAL, timeout=1200)
        except FileNotFoundError as exc:
            attempts.append(f"{unshare[0]}: {exc}")
            break
        if READY in result.stderr:
            return result
        attempts.append(f"{' '.join(unshare)}: exit {result.returncode}: {result.stderr.strip()[-300:]}")
    message = "cannot set up a read-only sandbox (private mount namespace): " + "; ".join(attempts)
    if os.environ.get("WBC_REQUIRE_SANDBOX"):
        pytest.fail(f"WBC_REQUIRE_SANDBOX is set but {message}")
    pytest.skip(message)


@pytest.mark.slow  # compiles every kernel in memory (~20 s)
def test_a_read_only_install_compiles_in_memory_and_says_how_to_cache(tmp_path):
    home = tmp_path / "home"
    home.mkdir()
    env = {name: value for name, value in os.environ.items() if name not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME")}
    env["HOME"] = str(home)
    result = _in_read_only_sandbox(PROGRAM, [PACKAGE, home], env)
    assert result.returncode == 0, result.stderr
    notice = _cache.NO_CACHE_MESSAGE.format(folder=PACKAGE / "runtime" / "kernels")
    assert "NUMBA_CACHE_DIR" in notice
    assert result.stderr.count(notice) == 1, result.stderr
    assert "Traceback" not in result.stderr and "RuntimeError" not in result.stderr, result.stderr
    summary, command = result.stdout.strip().rsplit("\n", 1)
    assert json.loads(summary)[0]["scenario"], summary
    robot = wbc.load_robot("youbot")  # the same tick out of the sandbox (cached kernels): the same command
    expected = wbc.Controller(robot, [wbc.PostureTask(1.0, gain=0.5)], [wbc.JointVelocityLimits()]).step(np.array(Q))
    np.testing.assert_allclose(json.loads(command), expected, rtol=1e-12, atol=1e-12)
