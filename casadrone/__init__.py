"""casadrone: racing-drone airframe optimisation on CasADi and pymoo."""

__version__ = "0.1.0"
