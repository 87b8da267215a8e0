"""What the ROS 2 node adds to a tick, and the DDS round trip alone, on loopback.

    python benchmarks/ros_latency.py [--ticks 10000] [--repeats 3]

Runs itself again inside a private network namespace (``unshare -n`` as root, ``unshare -rn``
otherwise; ``lo`` the only interface, Cyclone on loopback, multicast off): no packet leaves
the machine. Per repeat:

* **node**: ``wbc ros youbot_circle --config youbot`` against the simulated robot
  (``python -m wbc.ros.simulated``) for ``ticks`` control ticks; from its summary, the added
  latency (the tick's start, when it takes the newest state from DDS, to the return of the
  last command's write: ``latency``) beside the bare controller step (``step``), p50/p99;
* **round trip**: a Float64MultiArray of 5 values written by one process, echoed by another,
  read back: p50/p99 over ``ticks`` round trips.

Numbers depend on the machine and its load: read the ratio latency / step, and compare runs
made on the same machine in one session.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

SCENARIO, CONFIG = "youbot_circle", "youbot"
ECHO = "/wbc_bench/echo"


def _namespace() -> list[str]:
    for unshare in (["unshare", "-n"], ["unshare", "-rn"]):
        if subprocess.run([*unshare, "true"], capture_output=True).returncode == 0:
            return unshare
    sys.exit("ros_latency: no private network namespace (unshare -n / unshare -rn): not run")


def _node_run(ticks: int) -> dict[str, float]:
    sim = subprocess.Popen([sys.executable, "-m", "wbc.ros.simulated", SCENARIO, "--config", CONFIG],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(2.0)  # the robot publishes before the node starts: every tick of the node controls
        duration = ticks * 0.01
        node = subprocess.run([sys.executable, "-m", "wbc", "ros", SCENARIO, "--config", CONFIG, "--json",
                               "--duration", str(duration)], capture_output=True, text=True,
                              timeout=duration + 300)
        if node.returncode != 0:
            sys.exit(f"node failed: {node.stderr[-3000:]}")
        return json.loads(node.stdout)
    finally:
        sim.terminate()
        sim.wait(timeout=30)


def _echo(seconds: float) -> None:
    """The echo process: every Float64MultiArray on ECHO/ping back on ECHO/pong."""
    from wbc.ros.dds import Participant, take_one
    from wbc.ros.messages import Float64MultiArray

    participant = Participant()
    reader, writer = participant.reader(ECHO + "/ping", Float64MultiArray), participant.writer(
        ECHO + "/pong", Float64MultiArray)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        sample, more = take_one(reader)
        if sample is not None:
            writer.write(sample)
        elif not more:
            time.sleep(0)


def _round_trips(count: int) -> np.ndarray:
    from wbc.ros.dds import Participant, take_one
    from wbc.ros.messages import Float64MultiArray

    echo = subprocess.Popen([sys.executable, __file__, "--echo", str(count * 0.01 + 60)])
    try:
        participant = Participant()
        writer, reader = participant.writer(ECHO + "/ping", Float64MultiArray), participant.reader(
            ECHO + "/pong", Float64MultiArray)
        message = Float64MultiArray(data=[0.1, 0.2, 0.3, 0.4, 0.5])
        times = np.empty(count)
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:  # matched both ways: one echo arrives
            writer.write(message)
            time.sleep(0.05)
            if take_one(reader)[0] is not None:
                break
        while take_one(reader)[1]:
            pass
        for k in range(count):
            start = time.perf_counter()
            writer.write(message)
            while take_one(reader)[0] is None:
                if time.perf_counter() - start > 5:
                    sys.exit("round trip: no echo in 5 s")
            times[k] = time.perf_counter() - start
            time.sleep(0.001)
        return times
    finally:
        echo.terminate()
        echo.wait(timeout=30)


def inside(ticks: int, repeats: int) -> None:
    from wbc.ros.dds import LOOPBACK_CONFIG, loopback_only

    loopback_only()
    os.environ["CYCLONEDDS_URI"] = LOOPBACK_CONFIG
    us = 1e6
    for repeat in range(repeats):
        summary = _node_run(ticks)
        trips = _round_trips(ticks)
        print(f"repeat {repeat + 1}: node over {summary['control_ticks']} control ticks: added latency p50 "
              f"{summary['latency_p50_us']:.0f} us, p99 {summary['latency_p99_us']:.0f} us; bare step p50 "
              f"{summary['step_p50_us']:.0f} us, p99 {summary['step_p99_us']:.0f} us (latency / step p50 "
              f"{summary['latency_p50_us'] / summary['step_p50_us']:.1f}x); overruns {summary['overruns']}; "
              f"DDS round trip p50 {np.percentile(trips, 50) * us:.0f} us, p99 {np.percentile(trips, 99) * us:.0f} us",
              flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ticks", type=int, default=10_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--inside", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--echo", type=float, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.echo is not None:
        _echo(args.echo)
    elif args.inside:
        inside(args.ticks, args.repeats)
    else:
        environment = {key: value for key, value in os.environ.items() if not key.startswith(("ROS_", "CYCLONEDDS"))}
        sys.exit(subprocess.run([*_namespace(), sys.executable, __file__, "--inside", "--ticks", str(args.ticks),
                                 "--repeats", str(args.repeats)], env=environment).returncode)


if __name__ == "__main__":
    main()
