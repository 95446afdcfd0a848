"""casadrone command line: a thin typer layer over the public API (docs/reference/cli.md).

Every command that prints results also takes ``--json``. Bad input (a config problem, a bad
``key=value`` override, an unknown option) prints one ``FILE: key: message`` line per problem on
stderr and exits with code 2, without a traceback. Heavy modules (CasADi, the chain) are imported
inside the commands, so ``casadrone validate`` stays fast.

The commands are grouped by layer: :mod:`~casadrone.cli.design` (validate, trim, linearise, lqr),
:mod:`~casadrone.cli.flight` (simulate, benchmark), :mod:`~casadrone.cli.limit` (limit-lap),
:mod:`~casadrone.cli.codesign` (codesign),
:mod:`~casadrone.cli.massprops` (massprops), :mod:`~casadrone.cli.trimstudy` (trim-study),
:mod:`~casadrone.cli.propulsion` (fit-propulsion), :mod:`~casadrone.cli.parts` (parts),
:mod:`~casadrone.cli.optimisation` (run, resume, decide, compare, report) and
:mod:`~casadrone.cli.export` (export), all registered on the one :data:`app` of
:mod:`~casadrone.cli.common`, the console entry point ``casadrone.cli:app``.
"""

from __future__ import annotations

# Importing the command modules registers their commands on ``app``; their order is the order of
# ``casadrone --help``. Only ``app`` is public here: import anything else from its module.
from casadrone.cli import (  # noqa: F401 (importing registers the commands)
    build,
    codesign,
    design,
    export,
    flight,
    limit,
    massprops,
    optimisation,
    parts,
    propulsion,
    trimstudy,
)
from casadrone.cli.common import app, command_name, unwrapped
from casadrone.cli.examples import epilog

for _command in app.registered_commands:  # every --help ends with its examples
    _command.epilog = _command.epilog or epilog(command_name(_command))
    if _command.help is None and _command.callback is not None and _command.callback.__doc__:
        _command.help = unwrapped(_command.callback.__doc__)  # wrapped by the terminal's width

__all__ = ["app"]
