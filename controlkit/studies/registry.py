"""The studies' registry entries: :class:`Study` (``reproduce``) and :class:`Robustness`.

A study is a folder of :mod:`controlkit.studies` whose ``__init__`` defines ``STUDY``, a
:class:`Study`; :data:`controlkit.studies.STUDIES` lists them. Nothing else names a
study: the command line, ``reproduce`` and ``sweep`` read these entries.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass, field


class UsageError(ValueError):
    """A bad argument of a study (the command line exits with status 2).

    Examples
    --------
    >>> from controlkit.studies.reproduce import reproduce
    >>> try:
    ...     reproduce("moon")
    ... except UsageError as error:
    ...     print(error)
    unknown study 'moon'; choose from ['all', 'spacecraft', 'cmg', 'frit']
    """



@dataclass(frozen=True)
class Robustness:
    """A study's robustness sweep: what is drawn, what one run returns, what success is.

    :func:`controlkit.studies.robustness.study` runs it over seeded draws (or a grid) of
    :attr:`ranges` with :func:`controlkit.sweep.sweep` and summarises it per case; the
    command line's ``controlkit sweep <study>`` offers every study that has one.

    Attributes
    ----------
    run : callable
        ``run(case, **drawn, horizon=None) -> dict`` of metrics of one run.
    ranges : dict
        Drawn parameter to its ``(low, high)`` range (uniform draws).
    default_cases : callable
        ``default_cases() -> tuple of str``: the cases compared when none is named.
    cases : callable
        ``cases() -> collection of str``: every case the study knows.
    success : str
        The boolean metric counted as a success.
    error : str
        The metric whose median the summary reports.
    binned : callable
        ``binned(rows, span) -> (key, list of dicts)``: the success rate in bins of a
        drawn parameter, for one case's rows (a DataFrame; ``span`` the ranges in force).
    warmup : callable
        ``warmup(cases)``: compile each case's loop before the workers start.
    write : callable
        ``write(table, summary, out, **settings) -> list of paths``: the study's files.
    extra_draws : dict
        Further distributions drawn with the ranges (e.g. a random rotation axis).

    Examples
    --------
    >>> from controlkit.studies import STUDIES
    >>> STUDIES["cmg"].robustness.ranges
    {'friction_scale': (0.0, 5.0), 'inertia_scale': (0.8, 1.2)}
    """

    run: Callable
    ranges: dict
    default_cases: Callable
    cases: Callable
    success: str
    error: str
    binned: Callable
    warmup: Callable
    write: Callable
    extra_draws: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Study:
    """What ``controlkit reproduce <study>`` runs and writes: a study's registry entry.

    Attributes
    ----------
    name : str
        Study name on the command line and output sub-folder.
    cases : tuple of str
        Every case the study knows.
    default_cases : tuple of str
        Cases run when none is named.
    run : callable
        ``run(case, horizon, progress, engine) -> TimeResponseData``; ``horizon=None``
        means the published one.
    table : callable
        Response to CSV columns (dict of arrays).
    metrics : callable
        CSV columns (of :attr:`table`) to a JSON-ready dict.
    figures : callable
        ``figures({case: table}, outdir) -> list of paths``.
    default_stride : int
        CSV row stride when ``--stride`` is not given.
    csv_stem : callable
        Case name to CSV file stem.
    csv_columns : callable
        Table to the columns written to CSV (default: all).
    figure_stems : tuple of str
        The figures ``figures`` can draw one at a time (``stems=[stem]``), so that they
        are drawn in parallel worker processes; empty: ``figures`` is called once.
    draw_first : tuple of str
        Figures handed to the workers before the others because they take longest, so
        that the workers finish together.
    figure_columns : callable, optional
        ``figure_columns(stem)``: the table columns a figure reads (the workers are sent
        only those); default all.
    simulation_cost : float
        Relative time to simulate the study's cases; cheaper studies run first, so their
        figures are drawn by the workers while the costlier simulations run.
    write : callable, optional
        For a study whose cases are not single runs: ``write({case: result}, folder)
        -> (metrics, paths)`` writes all its files; ``table``, ``metrics`` and
        ``figures`` are then unused.
    in_all : bool
        Whether ``controlkit reproduce all`` runs it (the papers' results do; the
        sensitivity study is asked for by name).
    Ts : float
        Sampling period of its loops (to check a horizon before anything runs).
    horizon : float
        Its published horizon, s.
    signals : int
        About how many numbers one sample holds (states and outputs), to size a run.
    streaming : callable, optional
        ``streaming(case, horizon) -> accumulator`` for studies whose runs can be
        streamed: the run then holds no more than the figures' samples, the CSV rows are
        written as they are computed, and ``accumulator.metrics()`` gives the metrics
        from every sample.
    stems_for : callable, optional
        ``stems_for(cases) -> tuple of str``: the figures drawn for these cases
        (default: all of :attr:`figure_stems`).
    robustness : Robustness, optional
        The study's robustness sweep (``controlkit sweep <study>``), if it has one.
    horizon_note : callable, optional
        ``horizon_note(seconds) -> str or None``: what a run that short cannot show of
        the study's claim (the command line prints it after the results).
    extra : callable, optional
        ``extra(metrics, folder, engine, options) -> (paths, (figures, tables, stems) or
        None)``: files a study writes from its cases' metrics once they are all run (the
        spacecraft's frequency-domain bounds), and figures for the workers to draw.

    Examples
    --------
    >>> from controlkit.studies import STUDIES
    >>> STUDIES["spacecraft"].default_cases
    ('ideal', 'without_mec', 'proposed')
    """

    name: str
    cases: tuple[str, ...]
    default_cases: tuple[str, ...]
    run: Callable
    table: Callable
    metrics: Callable
    figures: Callable
    default_stride: int = 1
    csv_stem: Callable[[str], str] = str
    csv_columns: Callable[[dict], dict] = lambda columns: columns
    figure_stems: tuple[str, ...] = ()
    draw_first: tuple[str, ...] = ()
    figure_columns: Callable[[str], tuple[str, ...]] | None = None
    simulation_cost: float = 1.0
    write: Callable | None = None
    in_all: bool = True
    Ts: float = 0.1
    horizon: float = 20_000.0
    signals: int = 60
    streaming: Callable | None = None
    stems_for: Callable | None = None
    robustness: Robustness | None = None
    horizon_note: Callable[[float], str | None] | None = None
    extra: Callable | None = None

    def stems(self, cases) -> tuple[str, ...]:
        """The figures drawn for ``cases`` (see :attr:`stems_for`)."""
        return self.figure_stems if self.stems_for is None else self.stems_for(cases)



def scenario_runner(scenario):
    """``run(case, horizon, progress, engine, **options)`` of a study's scenario module.

    ``horizon=None`` means the published one (``scenario.HORIZON``); an option the
    scenario's ``run`` does not take is refused with the ones it does. Keywords that
    ``run`` passes on through ``**kwargs`` are those the scenario lists in
    ``RUN_KEYWORDS``. When the scenario defines ``options_read(case) -> set``, the
    options a case actually reads, ``run.reads`` is that function (so that an option no
    case of a run reads is refused rather than silently ignored).

    Examples
    --------
    >>> from controlkit.studies.cmg import scenario
    >>> run = scenario_runner(scenario)
    >>> try:
    ...     run.check({"gain": 1.0})
    ... except UsageError as error:
    ...     print(error)  # doctest: +NORMALIZE_WHITESPACE
    unknown option ['gain'] for controlkit.studies.cmg.scenario.run; options: ['C1', 'C2',
    'C3', 'C4', 'Ts', 'boundary_layer', 'eta1', 'eta2', 'gamma1', 'gamma2', 'gamma3',
    'gamma4', 'plant_options', 'x0']
    """
    parameters = inspect.signature(scenario.run).parameters.values()
    accepted = {p.name for p in parameters
                if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)} - {
        "case", "horizon", "progress", "engine", "compile"}
    accepted |= set(getattr(scenario, "RUN_KEYWORDS", ()))

    def check(options):
        unknown = sorted(set(options) - accepted - {"record_every", "on_chunk"})
        if unknown:
            raise UsageError(f"unknown option {unknown} for {scenario.__name__}.run; "
                             f"options: {sorted(accepted)}")

    def run(case, horizon, progress, engine, **options):
        check(options)
        return scenario.run(case, horizon=horizon or scenario.HORIZON, progress=progress,
                            engine=engine, **options)

    run.check = check
    if hasattr(scenario, "options_read"):
        run.reads = scenario.options_read
    return run
