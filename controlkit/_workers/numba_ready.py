"""Imported by a sweep's forkserver (:func:`controlkit.sweep.executors.prestart`): numba
imported, with controlkit's additions registered, once, so that each worker forked from it
loads compiled modules without paying for the import. It starts no thread.
"""

from .. import _jit

if _jit.available():
    _jit.numba_module()
