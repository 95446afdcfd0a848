"""casadrone: racing-drone airframe optimisation on CasADi and pymoo.

The public API, one function per stage of the chain (docs/concepts/chain.md)::

    import casadrone as cd
    frame = cd.build_airframe(cd.load_airframe("SY250", ["alpha_deg=80"]))
    tp = cd.trim(frame, "hover", solver="newton")
    lin = cd.linearise(frame, tp)
    design = cd.design_lqri(lin, cd.load_controller())
    ev = cd.evaluate(cd.theta_of(cd.load_airframe("HS210")), cd.default_setup("HS210"))

Most names are imported lazily. casadrone's parallelism is one
process per core; its linear algebra is on 20×20 matrices, where a multi-threaded BLAS is up to 5×
slower than one thread, so the BLAS thread pools default to one thread unless set before import.
"""

import importlib as _importlib
import os as _os
import sys as _sys
import types as _types

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")

__version__ = "0.1.0"

_API = {
    "casadrone.config.io": ["ConfigError", "load"],
    "casadrone.config.airframe": ["load_airframe", "AirframeConfig"],
    "casadrone.config.controller": ["load_controller", "ControllerConfig"],
    "casadrone.config.problem": ["ProblemConfig", "BackendConfig"],
    "casadrone.config.track": ["TrackConfig"],
    "casadrone.config.propulsion": ["PropulsionConfig", "PropellerConfig", "MotorConfig",
                                    "BatteryConfig"],
    "casadrone.config.codesign": ["CodesignProblemConfig"],
    "casadrone.optimise.checks": ["load_problem", "validate_file"],
    "casadrone.massprops": ["mass_properties", "MassProperties"],
    "casadrone.airframe": ["Airframe", "build_airframe", "with_theta", "TABLE1_BOUNDS",
                           "THETA_KEYS"],
    "casadrone.model": ["quadrotor_model", "STATE_NAMES", "INPUT_NAMES"],
    "casadrone.trim": ["trim", "trim_all", "TrimPoint", "TrimOptions"],
    "casadrone.conditions": ["OperatingPoint", "CONDITIONS"],
    "casadrone.trimstudy": ["trim_study", "StudyOptions", "TrimStudy"],
    "casadrone.linearise": ["linearise", "LinearModel"],
    "casadrone.control": ["design_lqri", "design_for", "robustness_ensemble", "hover_point",
                          "LQRIDesign"],
    "casadrone.simulate": ["simulate", "Trajectory", "SimOptions"],
    "casadrone.indices": ["compute_indices", "interval_table", "register_index",
                          "unregister_index", "INDICES"],
    "casadrone.evaluate": ["evaluate", "default_setup", "theta_of", "Evaluation",
                           "EvaluationSetup"],
    "casadrone.thruststand": ["read_log", "fit_propulsion", "StandLog", "PropulsionFit",
                              "LogError"],
    "casadrone.limit.lap": ["limit_lap"],
    "casadrone.limit.result": ["LimitLap", "LimitLapOptions"],
    "casadrone.optimise.runner": ["run", "resume", "RunResult"],
    "casadrone.rundir.store": ["RunStore"],
    "casadrone.decide": ["decide", "Decision"],
    "casadrone.benchmark": ["run_benchmark"],
    "casadrone.compare": ["gain_pct"],
    "casadrone.codesign.checks": ["load_codesign_problem"],
    "casadrone.codesign.driver": ["CodesignResult"],
    "casadrone.export": ["write_export", "FORMATS"],
    "casadrone.export.source": ["source_of", "ExportSource"],
    "casadrone.report": ["write_report"],
}
#: Functions named like their package (``casadrone.codesign.codesign``,
#: ``casadrone.export.export``): documented with the API, imported from their package
#: (``from casadrone.export import export``), not re-exported, since ``casadrone.codesign`` and
#: ``casadrone.export`` name the packages (``import casadrone.codesign.polish as p`` must work).
_PACKAGE_FUNCTIONS = {"casadrone.codesign": ["codesign"], "casadrone.export": ["export"]}
_WHERE = {name: module for module, names in _API.items() for name in names}

#: Stage functions named like their modules (``casadrone.trim.trim`` …). Importing a submodule
#: makes Python set the package attribute of its name to the module, which would shadow the
#: function; the facade's module class refuses that, so the names stay lazy and ``import
#: casadrone.config`` imports no CasADi.
_STAGE_FUNCTIONS = {"decide": "casadrone.decide", "evaluate": "casadrone.evaluate",
                    "linearise": "casadrone.linearise", "simulate": "casadrone.simulate",
                    "trim": "casadrone.trim"}
_WHERE.update(_STAGE_FUNCTIONS)
#: The public names, written out so that tools reading the source (type checkers, editors,
#: griffe) see them; tests/unit/test_public_api.py checks it is exactly the names above.
__all__ = [
    "Airframe", "AirframeConfig", "BackendConfig", "BatteryConfig", "CONDITIONS",
    "CodesignProblemConfig", "CodesignResult", "ConfigError", "ControllerConfig", "Decision",
    "Evaluation", "EvaluationSetup", "ExportSource", "FORMATS", "INDICES", "INPUT_NAMES",
    "LQRIDesign", "LimitLap", "LimitLapOptions", "LinearModel", "LogError", "MassProperties",
    "MotorConfig", "OperatingPoint", "ProblemConfig", "PropellerConfig", "PropulsionConfig",
    "PropulsionFit", "RunResult", "RunStore", "STATE_NAMES", "SimOptions", "StandLog",
    "StudyOptions", "TABLE1_BOUNDS", "THETA_KEYS", "TrackConfig", "Trajectory", "TrimOptions",
    "TrimPoint", "TrimStudy", "build_airframe", "compute_indices", "decide", "default_setup",
    "design_for", "design_lqri", "evaluate", "fit_propulsion", "gain_pct", "hover_point",
    "interval_table", "limit_lap", "linearise", "load", "load_airframe", "load_codesign_problem",
    "load_controller", "load_problem", "mass_properties", "quadrotor_model", "read_log",
    "register_index", "resume", "robustness_ensemble", "run", "run_benchmark", "simulate",
    "source_of", "theta_of", "trim", "trim_all", "trim_study", "unregister_index", "validate_file",
    "with_theta", "write_export", "write_report",
]


class _Facade(_types.ModuleType):
    def __setattr__(self, name: str, value: object) -> None:
        if name in _STAGE_FUNCTIONS and isinstance(value, _types.ModuleType):
            return
        super().__setattr__(name, value)


_sys.modules[__name__].__class__ = _Facade


def __getattr__(name: str):
    if name in _WHERE:
        value = getattr(_importlib.import_module(_WHERE[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'casadrone' has no attribute {name!r}")
