"""Scenes: one TOML file from snapshot to picture, computing only what its styles read.

``load_scene`` (model.py) validates the file; ``make_plan`` (plan.py) derives the snapshots and
the attribute set, and ``explain``s it; ``LinesCache`` (cache.py) keeps traced lines keyed by
their inputs; ``run_scene`` (run.py) runs the stages.
"""

from .cache import LinesCache
from .model import Scene, SceneError, View, load_scene, scene_from_dict
from .plan import Plan, make_plan
from .run import RunResult, run_scene

__all__ = ["LinesCache", "Plan", "RunResult", "Scene", "SceneError", "View", "load_scene",
           "make_plan", "run_scene", "scene_from_dict"]
