"""Benchmark suites of wbc (not part of the installed package; run from a source checkout).

    python -m benchmarks.dataset    # record the QP of every tick of every tasks/*.toml
    python -m benchmarks.solvers    # qpsolvers backends on the recorded QPs (qpbenchmark on the test set)
    python -m benchmarks.solvers --workers 2   # the same on 2 local Dask worker processes (or --scheduler ADDRESS)
    qpbenchmark benchmarks/wbc_qpbenchmark.py --results-path results.csv run   # the test set, qpbenchmark's CLI
    python -m benchmarks.peers      # wbc vs Pink, mink and placo, interleaved tick by tick
    python -m benchmarks.scaling    # tick cost vs DOF and vs number of tasks
    pytest benchmarks/test_micro.py --benchmark-only   # hot-path micro-benchmarks

See benchmarks/README.md for the methodology and the measured numbers.
"""
