"""caveflow's Ray driver: a study's variants as Ray tasks (see :mod:`caveflow_ray.driver`)."""

from .driver import main, plan, run_variant

__all__ = ["main", "plan", "run_variant"]
