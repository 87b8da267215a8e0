"""The core: what every layer above the runtime shares.

* :mod:`wbc.core.errors` -- the exceptions (every one a :class:`~wbc.core.errors.WbcError`);
* :mod:`wbc.core.validation` -- the checks at the API boundary;
* :mod:`wbc.core.settings` -- the validated settings of tasks and constraints;
* :mod:`wbc.core.schema` -- the strict schemas of wbc's TOML files;
* :mod:`wbc.core.outcome` -- what answered a tick (the fallback chain's enum);
* :mod:`wbc.core.quiet` -- native output kept off the terminal.

It imports only the runtime (:mod:`wbc.runtime.kernels`: the pose check of
:func:`~wbc.core.validation.as_pose` is one compiled call).
"""
