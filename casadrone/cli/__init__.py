"""casadrone command line: a thin typer layer over the public API (DESIGN.md §10).

Every command that prints results also takes ``--json``. Bad input (a config problem, a bad
``key=value`` override, an unknown option) prints one ``FILE: key: message`` line per problem on
stderr and exits with code 2, without a traceback. Heavy modules (CasADi, the chain) are imported
inside the commands, so ``casadrone validate`` stays fast.

The commands are grouped by layer: :mod:`~casadrone.cli.design` (validate, trim, linearise, lqr),
:mod:`~casadrone.cli.flight` (simulate, benchmark), :mod:`~casadrone.cli.limit` (limit-lap) and :mod:`~casadrone.cli.optimisation` (run,
resume, decide, compare, report), all registered on the one :data:`app` of
:mod:`~casadrone.cli.common`, the console entry point ``casadrone.cli:app``.
"""

from __future__ import annotations

# The imports register the commands; their order is the order of ``casadrone --help``.
from casadrone.cli.common import (  # noqa: F401 (re-exported)
    EXIT_BAD_INPUT,
    AirframeArg,
    JsonOpt,
    OverridesArg,
    PlotOpt,
    app,
    bad_input,
    check_plot_dir,
    jsonable,
    load_airframe_or_exit,
    print_json,
    reports_config_errors,
    save_figures,
)
from casadrone.cli.design import (  # noqa: F401 (re-exported)
    Condition,
    LinMethod,
    TrimSolver,
    linearise,
    lqr,
    trim,
    validate,
)
from casadrone.cli.flight import INTERVAL_KEYS, IntegratorName, benchmark, simulate  # noqa: F401
from casadrone.cli.limit import LIMIT_KEYS, limit_lap_command  # noqa: F401
from casadrone.cli.optimisation import (  # noqa: F401 (re-exported)
    BackendName,
    BackendOpt,
    DecideMethod,
    QuietOpt,
    ReferenceOpt,
    RunDirArg,
    SchedulerOpt,
    WorkersOpt,
    backend_config,
    compare,
    decide_command,
    open_problem,
    report,
    require_run_dir,
    resume,
    run_command,
    run_error,
    run_summary,
)
from casadrone.config import ConfigError  # noqa: F401 (re-exported)
