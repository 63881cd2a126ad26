"""controlkit: block diagrams for robust nonlinear attitude control, on python-control.

Subpackages: ``blocks`` (one ``NonlinearIOSystem`` factory per element of the papers),
``diagrams`` (the papers' figures as ``control.interconnect`` calls), ``scenarios``
(published parameter sets and cases), ``outputs`` (metrics, figures, files); modules
``sampling`` (zero-order hold for any continuous nlsys), ``simulation`` and ``engine``
(python-control's simulator or the compiled fast path), ``drawing`` (block diagrams).
"""

__version__ = "0.1.0"
