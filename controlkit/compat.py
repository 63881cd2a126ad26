"""The one place where controlkit uses what its dependencies do not publish.

Everything else uses public APIs only (``tests/test_architecture.py`` checks it). Each
use here says what it is for and what would replace it; each is tested against the
versions ``pyproject.toml`` admits (``tests/test_compat.py``), so an upgrade that breaks
one fails there, by name, instead of somewhere deep in a run.

python-control (0.10.x):

- :func:`timeresp_arguments`: the drop-in :func:`controlkit.input_output_response` reads
  its arguments, their aliases (``T``, ``U``, ``X0``, ``return_x``, ``t_eval``) and
  their legacy positions exactly as :func:`control.input_output_response` does, with
  python-control's own helpers (``control.config._process_kwargs`` and
  ``_process_param``), so that a call written for one reads the same with the other.
- :func:`inputs_and_state`: the input array and the initial state as python-control
  shapes them (``control.timeresp._check_convert_array`` and
  ``control.nlsys._process_vector_argument``: lists of per-signal parts, a short
  initial state padded with zeros and its warning).

- :data:`SYSTEM_CALLS`: a python-control system keeps the ``params`` of its last
  ``output``/``dynamics`` call on itself (``_current_params``; an interconnect hands them
  to its subsystems the same way), so two threads calling one system with different
  parameters read each other's. controlkit calls python-control's systems (its own runs,
  Python blocks of the engine, the reference) under this lock, one thread at a time, so
  that a run on threads answers as the same run alone. Would go if python-control passed
  ``params`` down its calls instead.

numba (0.59-0.68):

- :func:`unique_function_ids`: numba names the compiled code of a function after it and
  a per-process counter; two processes compiling the same function give it the same
  name, and when code cached by both is loaded into one process the second copy is bound
  to the first's environment (numba issue 10486: "'descr' is NULL" on return). A random
  128-bit id per function avoids it (PyTensor does the same).
"""

from __future__ import annotations

import threading
import uuid

#: Held while controlkit calls a python-control system (see the module's description):
#: re-entrant, as a user's function may run a diagram of its own.
SYSTEM_CALLS = threading.RLock()


def timeresp_arguments(kwargs, timepts, inputs, initial_state, return_states,
                       evaluation_times):
    """``(T, U, X0, return_x, t_eval)`` read as :func:`control.input_output_response`
    reads them, aliases and all; what is left of ``kwargs`` is python-control's to refuse.

    Examples
    --------
    >>> timeresp_arguments({"U": 2.0}, [0, 1], 0.0, 0.0, False, "T")[1]
    2.0
    """
    if not kwargs:  # (no alias given: the arguments as they are, 3 us sooner)
        return timepts, inputs, initial_state, return_states, evaluation_times
    from control.config import _process_kwargs, _process_param
    from control.timeresp import _timeresp_aliases

    aliases = _timeresp_aliases
    _process_kwargs(kwargs, aliases)
    T = _process_param("timepts", timepts, kwargs, aliases)
    U = _process_param("inputs", inputs, kwargs, aliases, sigval=0.0)
    X0 = _process_param("initial_state", initial_state, kwargs, aliases, sigval=0.0)
    return_x = _process_param("return_states", return_states, kwargs, aliases,
                              sigval=False)
    t_eval = _process_param("evaluation_times", evaluation_times, kwargs, aliases,
                            sigval="T")
    return T, U, X0, return_x, t_eval


def inputs_and_state(U, legal_shapes, X0, nstates):
    """``U`` checked against ``legal_shapes`` and ``X0`` padded to ``nstates`` values, as
    python-control does (with its messages and its warning for a short state).

    Examples
    --------
    >>> import numpy as np
    >>> U, X0 = inputs_and_state(np.ones(3), [(3,), (1, 3)], [1.0], 1)
    >>> U.shape, X0.tolist()
    ((3,), [1.0])
    """
    from control.nlsys import _process_vector_argument
    from control.timeresp import _check_convert_array

    U = _check_convert_array(U, legal_shapes, "Parameter `U`: ", squeeze=False)
    X0, _ = _process_vector_argument(X0, "X0", nstates)
    return U, X0


class _RandomIds:
    """An endless iterator of random 128-bit numbers (numba only calls ``next()``)."""

    def __iter__(self):
        return self

    def __next__(self) -> int:
        return uuid.uuid4().int


def unique_function_ids(numba) -> bool:
    """Give every function numba compiles in this process a random id (see the module's
    description); False when this numba has no such counter (nothing to do).

    Examples
    --------
    >>> from controlkit import _jit
    >>> not _jit.available() or unique_function_ids(_jit.numba_module())
    True
    """
    from numba.core.bytecode import FunctionIdentity

    if not hasattr(FunctionIdentity, "_unique_ids"):
        return False
    if not isinstance(FunctionIdentity._unique_ids, _RandomIds):
        FunctionIdentity._unique_ids = _RandomIds()
    return True
