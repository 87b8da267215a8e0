"""Long fuzz campaign: every example of tests/test_fuzz.py's case strategy, failures recorded
by signature instead of stopping at the first one.

    nice -n 10 python tests/fuzz_campaign.py --examples 3000 --out fuzz_campaign.json

HiGHS cases run in the worker subprocess (a crash is recorded and the worker restarted).
"""

import argparse
import collections
import json
import re
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from hypothesis import HealthCheck, given, settings  # noqa: E402

import test_fuzz as fuzz  # noqa: E402


def signature(case, message):
    message = re.sub(r"\[[^\]]*\]", "[..]", message, flags=re.S)
    first = message.strip().splitlines()[0] if message.strip() else "?"
    first = re.sub(r"-?\d+\.?\d*(e[-+]?\d+)?", "#", first)
    return f"{case['solver']} | {case['robot']} | {first[:300]}"


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--examples", type=int, default=1000)
    parser.add_argument("--out", default="fuzz_campaign.json")
    parser.add_argument("--seed", type=int, default=None)
    args = parser.parse_args()
    failures = collections.defaultdict(list)
    counts = collections.Counter()
    worker = fuzz.Worker()
    start = time.time()

    @settings(max_examples=args.examples, database=None, deadline=None, derandomize=False,
              suppress_health_check=list(HealthCheck))
    @given(case=fuzz.cases(solvers=fuzz.SOLVERS))
    def campaign(case):
        counts["examples"] += 1
        counts[f"solver {case['solver']}"] += 1
        try:
            if case["solver"] in fuzz.SUBPROCESS_SOLVERS:
                result = worker.run(case)
                if "failure" in result:
                    raise AssertionError(result["failure"])
            else:
                result = fuzz.run_case(case)
            counts["rejected" if "rejected" in result else "built"] += 1
            counts["ticks"] += len(result.get("statuses", []))
        except Exception as exc:  # noqa: BLE001 -- recorded, the campaign goes on
            message = f"{type(exc).__name__}: {exc}" if not isinstance(exc, AssertionError) else str(exc)
            key = signature(case, message)
            counts["failing examples"] += 1
            if len(failures[key]) < 3:
                failures[key].append({"case": case, "message": message[:2000]})
            else:
                failures[key].append(None)
        if counts["examples"] % 100 == 0:
            dump()

    def dump():
        summary = {"elapsed_s": time.time() - start, "counts": dict(counts),
                   "failures": {k: {"count": len(v), "examples": [e for e in v if e][:3]}
                                for k, v in sorted(failures.items(), key=lambda kv: -len(kv[1]))}}
        Path(args.out).write_text(json.dumps(summary, indent=1))
        print(f"{counts['examples']} examples, {counts['failing examples']} failing, "
              f"{len(failures)} signatures, {time.time() - start:.0f} s", flush=True)

    if args.seed is not None:
        from hypothesis import seed
        campaign = seed(args.seed)(campaign)
    campaign()
    dump()
    worker.close()


if __name__ == "__main__":
    main()
