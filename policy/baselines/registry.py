"""Policies by name, for the CLI and the evaluation harness. Entries are factories imported
lazily, so listing names (or importing this module) does not import torch; other packages add
theirs with `register_policy`."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from sim.gridworld import GridConfig

from ..base import Policy

#: factory(cfg=GridConfig | None, **kwargs) -> Policy
Factory = Callable[..., Policy]
_REGISTRY: dict[str, tuple[Factory, str]] = {}


def register_policy(name: str, factory: Factory, description: str = "") -> None:
    """Add (or replace) a named policy; the factory is only called by make_policy."""
    if not isinstance(name, str) or not name.strip() or any(c.isspace() for c in name):
        raise ValueError(f"policy names are non-empty words (got {name!r})")
    if not callable(factory):
        raise TypeError(f"factory for {name!r} must be callable (got {type(factory).__name__})")
    _REGISTRY[name] = (factory, description)


def known_policies() -> dict[str, str]:
    """name -> one-line description, sorted by name."""
    return {k: d for k, (_, d) in sorted(_REGISTRY.items())}


def make_policy(name: str, cfg: GridConfig | None = None, **kwargs: Any) -> Policy:
    """A fresh policy by name. kwargs go to the factory: `checkpoint` for the networks,
    `loop_guard` (True/False; None = the paper's choice) for every policy without truth."""
    if name not in _REGISTRY:
        raise KeyError(f"unknown policy {name!r}; known: {', '.join(sorted(_REGISTRY))}")
    return _REGISTRY[name][0](cfg=cfg, **kwargs)


def _plans(method: str) -> Factory:
    def make(cfg: GridConfig | None = None, loop_guard: bool | None = None, **_: Any) -> Policy:
        if loop_guard:
            raise ValueError("the plan policies replay optimal plans; loop detection does not apply")
        from ..groundtruth import PlanPolicy

        return PlanPolicy(method)

    return make


def _simple(module: str, cls_name: str) -> Factory:
    """A non-learned policy; the paper runs none of them under loop detection (NS's loop
    columns are '-'), so loop_guard defaults to off."""

    def make(cfg: GridConfig | None = None, loop_guard: bool | None = None, **_: Any) -> Policy:
        policy: Policy = getattr(importlib.import_module(f"{__package__}.{module}"), cls_name)()
        if loop_guard:
            from ..loops import LoopGuard

            return LoopGuard(policy)
        return policy

    return make


def _network(default: str) -> Factory:
    """The shipped network for the field's setting (<model>_<motion>_<distribution>.pt, e.g. the
    moving-target dual-stream rows of Table I) when one is shipped, else `default`."""
    model = default.split("_")[0]

    def make(cfg: GridConfig | None = None, checkpoint: Any = None, **kw: Any) -> Policy:
        from ..nn import load_policy, shipped_checkpoint

        if checkpoint is None:
            checkpoint = shipped_checkpoint(default)
            if cfg is not None and shipped_checkpoint(f"{model}_{cfg.motion}_{cfg.distribution}").is_file():
                checkpoint = shipped_checkpoint(f"{model}_{cfg.motion}_{cfg.distribution}")
        return load_policy(checkpoint, cfg=cfg, **kw)

    return make


def _drqn(cfg: GridConfig | None = None, checkpoint: Any = None, **_: Any) -> Policy:
    from ..drqn import DrqnPolicy
    from ..nn import shipped_checkpoint

    return DrqnPolicy.load(checkpoint or shipped_checkpoint("drqn_static_random"))


def _belief(cfg: GridConfig | None = None, prior: Any = None, loop_guard: bool | None = None,
            **_: Any) -> Policy:
    """prior: None (uniform), an (h, w) array, 'model' (the config's placement model) or a
    dataset path to estimate it from. The planner does not loop, so loop_guard is ignored."""
    from ..planner import BeliefPlanner

    return BeliefPlanner(prior=prior)


def _searchnet(cfg: GridConfig | None = None, checkpoint: Any = None, loop_guard: bool | None = None,
               temperature: float | None = None, **_: Any) -> Policy:
    """The shipped search network for the field's setting when one exists (static random
    otherwise: the network runs on any field size and motion)."""
    from ..nn import shipped_checkpoint
    from ..searchnet import load_searchnet_policy

    if checkpoint is None:
        checkpoint = shipped_checkpoint("searchnet_static_random")
        if cfg is not None:
            specific = shipped_checkpoint(f"searchnet_{cfg.motion}_{cfg.distribution}_{cfg.width}x{cfg.height}")
            generic = shipped_checkpoint(f"searchnet_{cfg.motion}_{cfg.distribution}")
            # altitude levels: the network with level planes (one for every field of up to 3 levels)
            levels = shipped_checkpoint(f"searchnet_{cfg.motion}_{cfg.distribution}_levels") if cfg.levels > 1 else None
            order = (specific, generic) if levels is None else (levels,)
            checkpoint = next((p for p in order if p.is_file()), checkpoint)
    policy: Policy = load_searchnet_policy(checkpoint, cfg, temperature=temperature or 0.0)
    if loop_guard is None:  # a greedy network can cycle where the belief stops changing: the
        loop_guard = cfg is None or not cfg.moving  # paper's guard for static targets, as for dualstream
        # with altitude levels the guard would count a climb or descent as a revisit of the cell
        # (a descent to recover and the climb back are three visits: its alpha)
        loop_guard = loop_guard and (cfg is None or cfg.levels == 1)
    if loop_guard:
        from ..loops import LoopGuard

        return LoopGuard(policy)
    return policy


register_policy("oracle", _plans("pt"), "optimal PT with full knowledge of the targets (upper bound)")
register_policy("cu", _plans("cu"), "closest unvisited target, with full knowledge (Eq. 2-3)")
register_policy("ns", _simple("ns", "NaivePolicy"), "naive solution: visible target, else vote (paper V-D)")
register_policy("frontier", _simple("frontier", "FrontierPolicy"), "greedy: nearest unvisited cell")
register_policy("lawnmower", _simple("lawnmower", "LawnmowerPolicy"),
                "boustrophedon sweep from the nearest corner")
register_policy("random", _simple("random_policy", "RandomPolicy"), "uniformly random valid moves")
register_policy("lawnmower-high", _simple("lawnmower_high", "HighLawnmowerPolicy"),
                "altitude levels: sweep lanes at the top level, then the close-up tour of every detection")
register_policy("drqn", _drqn, "DRQN baseline trained by reward (shipped checkpoint or --checkpoint)")
register_policy("dualstream", _network("dualstream_static_random"),
                "the dual-stream network (shipped checkpoint or --checkpoint)")
register_policy("searchnet", _searchnet,
                "search network on the belief state (DAgger on `belief`, then PPO; shipped or --checkpoint)")
register_policy("ssn", _network("ssn_static_random"),
                "split-stream baseline network (shipped checkpoint or --checkpoint)")
register_policy("belief", _belief, "belief-space planner: exact tour once all are sighted, else info per step")
