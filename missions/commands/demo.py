"""`uavsearch demo`: the main job on embedded defaults.

Today it evaluates the built-in policies on the paper's base case (static, random targets,
10 x 10, 5 targets) and prints Table I's columns; once the vehicle and the policy service are
wired it will fly the search on the simulated quadrotor too.
"""

from __future__ import annotations

from pathlib import Path

import typer

DEFAULT_POLICIES = ["oracle", "cu", "ns", "frontier", "lawnmower", "random"]


def register(app: typer.Typer) -> None:
    @app.command()
    def demo(
        episodes: int = typer.Option(1000, min=1, help="Test episodes per policy."),
        seed: int = typer.Option(2018, help="Seed of the test episodes."),
        out: Path = typer.Option(Path("out/demo"), help="Where the report goes."),
    ) -> None:
        """Evaluate the built-in policies on the base case and write a report."""
        from policy.baselines.registry import known_policies
        from policy.evaluation import run_eval
        from policy.nn import shipped_checkpoint
        from sim.gridworld import GridConfig

        names = [p for p in DEFAULT_POLICIES if p in known_policies()]
        for net in ("dualstream", "ssn", "drqn"):  # the learned ones whose checkpoint ships
            if net in known_policies() and shipped_checkpoint(f"{net}_static_random").exists():
                names.append(net)
        run_eval(names, GridConfig(), episodes, seed, out)
        typer.echo(f"report: {out.resolve()}")
