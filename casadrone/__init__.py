"""casadrone: racing-drone airframe optimisation on CasADi and pymoo.

The public API, one function per stage of the chain (DESIGN.md §1)::

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

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")

__version__ = "0.1.0"

_API = {
    "casadrone.configio": ["ConfigError", "load"],
    "casadrone.config": ["load_airframe", "load_controller", "AirframeConfig", "ControllerConfig"],
    "casadrone.problemconfig": ["load_problem", "ProblemConfig", "BackendConfig"],
    "casadrone.validation": ["validate_file"],
    "casadrone.massprops": ["mass_properties", "MassProperties"],
    "casadrone.airframe": ["Airframe", "build_airframe", "with_theta", "TABLE1_BOUNDS",
                           "THETA_KEYS"],
    "casadrone.model": ["quadrotor_model", "STATE_NAMES", "INPUT_NAMES"],
    "casadrone.trim": ["trim", "trim_all", "TrimPoint", "TrimOptions"],
    "casadrone.linearise": ["linearise", "LinearModel"],
    "casadrone.control": ["design_lqri", "design_for", "robustness_ensemble", "hover_point",
                          "LQRIDesign"],
    "casadrone.guidance": ["TrackConfig"],
    "casadrone.simulate": ["simulate", "Trajectory", "SimOptions"],
    "casadrone.indices": ["compute_indices", "interval_table", "register_index",
                          "unregister_index", "INDICES"],
    "casadrone.evaluate": ["evaluate", "default_setup", "theta_of", "Evaluation",
                           "EvaluationSetup"],
    "casadrone.optimise.runner": ["run", "resume", "RunResult"],
    "casadrone.optimise.store": ["RunStore"],
    "casadrone.decide": ["decide", "Decision"],
    "casadrone.benchmark": ["run_benchmark"],
    "casadrone.compare": ["gain_pct"],
    "casadrone.report": ["write_report"],
}
_WHERE = {name: module for module, names in _API.items() for name in names}
__all__ = sorted(_WHERE)

# Stage functions named like their modules (casadrone.trim.trim …) are bound eagerly: importing a
# submodule makes Python set the package attribute to the module, which would shadow a lazy name.
from casadrone.decide import decide as decide  # noqa: E402
from casadrone.evaluate import evaluate as evaluate  # noqa: E402
from casadrone.linearise import linearise as linearise  # noqa: E402
from casadrone.simulate import simulate as simulate  # noqa: E402
from casadrone.trim import trim as trim  # noqa: E402


def __getattr__(name: str):
    if name in _WHERE:
        value = getattr(_importlib.import_module(_WHERE[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'casadrone' has no attribute {name!r}")
