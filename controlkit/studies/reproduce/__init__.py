"""``controlkit reproduce``: run studies and write their CSV, metrics, figures and manifest.

Each study is one :class:`~controlkit.studies.registry.Study` entry of
:data:`controlkit.studies.STUDIES`; each case is one entry of its scenario's
``CASES``. Adding a study or a case adds no code here.

Under faults (see ``docs/sweeps.md``, "When things go wrong"):

- **One run per output folder.** The folder is locked
  (:class:`controlkit._lock.FolderLock`, file ``OUT/.lock``) while a run writes into it;
  a second run is refused with the holder's pid, command and start time. A lock left by
  a killed run is taken over at once.
- **run.json tells the truth.** Each study's manifest says, per case, ``done``,
  ``failed`` (with its ``error``), ``interrupted`` or ``skipped``; ``files`` lists the
  files of this run that exist, ``missing_files`` those that should have been written and
  are not (a figure that failed is in ``failed_figures``); ``complete`` is true only when
  every case is done and every file written.
- **Leftovers are cleaned at the next start.** A killed run leaves temporary files
  (``.NAME.PID.TOKEN.partial``) and a manifest with cases still ``pending`` or
  ``running``; the next run in the folder removes the former and corrects the latter
  (``interrupted``), in every study's folder.

The package's rooms: :mod:`.command` (:func:`reproduce` itself), :mod:`.checks` (every
argument, before anything is simulated), :mod:`.study` (one study's cases run and
written) and :mod:`.manifest` (``run.json``, and the cleaning of a killed run's leftovers).
"""

from .checks import CSV_BYTES_PER_SIGNAL, MEMORY_LIMIT, OWN_OPTIONS
from .checks import _horizons as _horizons  # the CLI's note on a short horizon
from .checks import _writable as _writable  # the sweep command checks its --out with it
from .command import LOCK_FILE, reproduce
from .manifest import MANIFEST
from .study import CASE_FAILURES, FIGURE_POINTS

__all__ = ["CASE_FAILURES", "CSV_BYTES_PER_SIGNAL", "FIGURE_POINTS", "LOCK_FILE", "MANIFEST",
           "MEMORY_LIMIT", "OWN_OPTIONS", "reproduce"]
