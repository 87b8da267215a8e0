"""The runtime: the compiled engine every tick runs on (the lowest layer; it imports nothing else of wbc).

* :mod:`wbc.runtime.kernels` -- the numba kernels (loaded on first use, cached on disk) and the
  layouts and opcodes they share with the items;
* :mod:`wbc.runtime.program` -- the tick program, a list of kernel calls run by one native call;
* :mod:`wbc.runtime.compiled_op` -- third-party ops that join that call.
"""
