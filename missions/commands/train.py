"""`uavsearch train`: fit the dual-stream network (or SSN) on a dataset with k-fold CV, the DRQN
baseline by reward in the grid world (no dataset), or the search network by DAgger + PPO (no
dataset either: the belief planner labels the states the student reaches)."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path

import typer

from sim.gridworld import GridConfig

from .options import DETECTION, LEVELS, with_grid, with_levels


class Model(StrEnum):
    dualstream = "dualstream"
    ssn = "ssn"
    drqn = "drqn"
    searchnet = "searchnet"


class Arch(StrEnum):
    small = "small"
    paper = "paper"


class Opt(StrEnum):
    sgd = "sgd"
    adam = "adam"


class Device(StrEnum):
    auto = "auto"
    cpu = "cpu"
    cuda = "cuda"


def register(app: typer.Typer) -> None:
    @app.command()
    @with_grid
    def train(
        dataset: Path | None = typer.Option(None, "--dataset",
                                            help="Directory written by `uavsearch synth` (not for drqn)."),
        out: Path = typer.Option(..., "--out", help="Run directory (checkpoints, metrics, plots)."),
        model: Model = typer.Option(Model.dualstream, "--model"),
        arch: Arch = typer.Option(Arch.small, "--arch", help="small (default) or the paper's layer sizes."),
        epochs: int = typer.Option(50, "--epochs", min=1),
        folds: int = typer.Option(10, "--folds", min=2, help="k of k-fold cross-validation."),
        run_folds: int | None = typer.Option(None, "--run-folds", min=1, help="Train only the first n folds."),
        batch: int = typer.Option(64, "--batch", min=1),
        lr: float = typer.Option(0.001, "--lr"),
        optimizer: Opt = typer.Option(Opt.sgd, "--optimizer", help="sgd (momentum 0.9, the paper) or adam."),
        seed: int = typer.Option(0, "--seed"),
        device: Device = typer.Option(Device.auto, "--device"),
        resume: bool = typer.Option(False, "--resume", help="Continue an interrupted run in --out."),
        threads: int | None = typer.Option(None, "--threads", min=1,
                                           help="torch CPU threads (default: 1 for small, torch's for paper)."),
        workers: int = typer.Option(1, "--workers", min=1, help="Train folds in this many local processes."),
        ray_address: str | None = typer.Option(None, "--ray-address",
                                               help="Send folds to this ray cluster (dataset on a shared path)."),
        ddp: int = typer.Option(0, "--ddp", min=0, help="DDP processes (GPUs) per fold; 0: off."),
        episodes: int = typer.Option(20_000, "--episodes", min=1, help="drqn: training episodes (the paper's 20k)."),
        dagger_iterations: int = typer.Option(6, "--dagger-iterations", min=0,
                                              help="searchnet: DAgger iterations (0: PPO only, with --init)."),
        dagger_episodes: int = typer.Option(400, "--dagger-episodes", min=1,
                                            help="searchnet: student rollouts per DAgger iteration."),
        ppo_updates: int | None = typer.Option(None, "--ppo-updates", min=0,
                                               help="searchnet: PPO updates after DAgger (default 20; 0 with "
                                                    "levels or masked fields, which PPO does not cover)."),
        ppo_episodes: int = typer.Option(128, "--ppo-episodes", min=1, help="searchnet: episodes per PPO update."),
        val_episodes: int = typer.Option(400, "--val-episodes", min=1,
                                         help="searchnet: validation episodes that pick the best network."),
        init: Path | None = typer.Option(None, "--init", exists=True, dir_okay=False,
                                         help="searchnet: fine-tune this checkpoint (DAgger with the student "
                                              "driving from iteration 0, then PPO) instead of starting from scratch."),
        beta0: float = typer.Option(1.0, "--dagger-beta0", min=0.0, max=1.0,
                                    help="searchnet: teacher share of the executed moves in the first "
                                         "student-driven DAgger iteration (halved each iteration)."),
        gps_sigma: float = typer.Option(0.0, "--gps-sigma", min=0.0,
                                        help="searchnet: GPS noise (m per axis) in the student's DAgger "
                                             "observations (Kalman fix, probabilistic map); 0: exact."),
        levels: int = LEVELS,
        detection: Path | None = DETECTION,
        field: Path | None = typer.Option(
            None, "--field", help="searchnet: train on this polygon field (field.json from `uavsearch field`): "
            "its grid and searchable cells (--width/--height are ignored)."),
        mask_class: list[str] | None = typer.Option(
            None, "--mask-class", help="searchnet: train on random masked fields of this class (repeat for "
            "several; sim.gridworld.mask_fields: convex, L, holes, strips)."),
        mask_area: int = typer.Option(100, "--mask-area", min=4, help="searchnet: searchable cells per random field."),
        agents: list[int] | None = typer.Option(
            None, "--agents", help="searchnet: a decentralised team network (issue 29, docs/fleet.md), DAgger from "
            "the team planner at these team sizes (repeat: --agents 2 --agents 4), warm-started from --init or "
            "the shipped single-agent network of the grid; --ppo-updates: MAPPO-style updates after it (default 0)."),
        team_planes: int = typer.Option(1, "--team-planes", min=1, max=2,
                                        help="searchnet --agents: teammates' input planes, 1 their cells, 2 also "
                                             "the cells another agent is nearer (the team's regions)."),
        *,
        grid: GridConfig,
    ) -> None:
        """Train on optimal decisions (the best fold's model goes to OUT/model.pt), or the DRQN by
        reward in the grid world set by the grid options (OUT/drqn.pt)."""
        if out.exists() and not out.is_dir():
            raise typer.BadParameter(f"{out} is a file; --out names a run directory", param_hint="--out")
        if model is Model.searchnet and agents:
            _train_team(out, grid, agents, init, seed, threads, workers, dagger_iterations,
                        dagger_episodes if dagger_episodes != 400 else None, epochs if epochs != 50 else None,
                        val_episodes if val_episodes != 400 else None, beta0 if beta0 != 1.0 else None,
                        ppo_updates or 0, ppo_episodes if ppo_episodes != 128 else None,
                        bool(levels > 1 or field is not None or mask_class or gps_sigma or resume), team_planes)
            return
        if agents:
            raise typer.BadParameter("--agents trains the team search network (--model searchnet)",
                                     param_hint="--agents")
        if model is Model.drqn:
            _train_drqn(out, episodes, seed, resume, threads, grid)
            return
        if model is Model.searchnet:
            fields = _fields(field, mask_class, mask_area, grid)
            if fields is not None and field is not None:
                grid = fields[0]
            grid = with_levels(grid, levels, detection)
            if ppo_updates is None:
                ppo_updates = 0 if levels > 1 or fields is not None else 20
            _train_searchnet(out, grid, seed, resume, threads, workers, ray_address, dagger_iterations,
                             dagger_episodes, ppo_updates, ppo_episodes, epochs if epochs != 50 else None,
                             init, beta0, val_episodes, gps_sigma, None if fields is None else fields[1])
            return
        if levels > 1 or field is not None or mask_class:
            raise typer.BadParameter("--levels, --field and --mask-class train the search network (--model searchnet)")
        ppo_updates = 20 if ppo_updates is None else ppo_updates
        if dataset is None:
            raise typer.BadParameter("dualstream and ssn learn from a dataset: give --dataset DIR",
                                     param_hint="--dataset")
        from policy.data import DatasetError
        from policy.training import TrainConfig
        from policy.training import train as run

        try:
            tc = TrainConfig(model=model.value, arch=arch.value, epochs=epochs, folds=folds, run_folds=run_folds,
                             batch=batch, lr=lr, optimizer=optimizer.value, seed=seed, device=device.value,
                             threads=threads, ddp=ddp)
            summary = run(dataset, out, tc, resume=resume, workers=workers, ray_address=ray_address)
        except DatasetError as e:
            raise typer.BadParameter(str(e), param_hint="--dataset") from e
        except (ValueError, RuntimeError) as e:  # CheckpointError is a ValueError
            raise typer.BadParameter(str(e)) from e
        typer.echo(
            f"{out}/model.pt: CV accuracy {100 * summary['cv_acc_mean']:.2f} ± {100 * summary['cv_acc_sd']:.2f} % "
            f"over {len(summary['folds'])} fold(s); best fold {summary['best_fold']}"
        )


def _train_searchnet(out: Path, grid: GridConfig, seed: int, resume: bool, threads: int | None, workers: int,
                     ray_address: str | None, iterations: int, dagger_episodes: int, ppo_updates: int,
                     ppo_episodes: int, epochs: int | None, init: Path | None = None, beta0: float = 1.0,
                     val_episodes: int = 400, gps_sigma: float = 0.0, fields=None) -> None:
    """DAgger on the belief planner, then PPO; no dataset (the teacher labels the student's own states).
    With levels (grid.levels > 1) the network has the level planes of L_max = 3 and climb/descend,
    and the teacher is the altitude planner; fields: a FieldSpec (masked fields), DAgger only."""
    import torch

    from policy.nn import CheckpointError
    from policy.searchnet.dagger import DaggerConfig
    from policy.searchnet.ppo import PpoConfig
    from policy.searchnet.train import SearchTrainConfig, train_searchnet

    torch.set_num_threads(threads or 1)
    try:
        dc = DaggerConfig(iterations=iterations, episodes=dagger_episodes, chunks=max(workers, 1), beta0=beta0,
                          gps_sigma=gps_sigma, fields=fields, **({"epochs": epochs} if epochs else {}))
        tc = SearchTrainConfig(dagger=dc, ppo=PpoConfig(episodes=ppo_episodes), ppo_updates=ppo_updates, seed=seed,
                               val_episodes=val_episodes, init=None if init is None else str(init),
                               level_planes=LEVEL_PLANES if grid.levels > 1 else 0)
    except ValueError as e:
        raise typer.BadParameter(str(e), param_hint="--dagger-iterations") from e
    try:
        path = train_searchnet(grid, out, tc, resume=resume, workers=workers, ray_address=ray_address,
                               log=typer.echo)
    except CheckpointError as e:
        raise typer.BadParameter(str(e), param_hint="--resume") from e
    typer.echo(f"{path}: the best search network (evaluate: uavsearch eval --policy searchnet --checkpoint {path})")


def _train_team(out: Path, grid: GridConfig, agents: list[int], init: Path | None, seed: int, threads: int | None,
                workers: int, iterations: int, episodes: int | None, epochs: int | None, val_episodes: int | None,
                beta0: float | None, mappo_updates: int, mappo_episodes: int | None, unsupported: bool,
                team_planes: int = 1) -> None:
    """`train --model searchnet --agents N`: policy.searchnet.teamtrain (the given options
    override TeamDaggerConfig's defaults, which are sized for a shared CPU)."""
    import torch

    from policy.nn import CheckpointError, shipped_checkpoint
    from policy.searchnet.teamdagger import TeamDaggerConfig
    from policy.searchnet.teamtrain import TeamTrainConfig, train_team

    if unsupported:
        raise typer.BadParameter("the team network trains at one height on the whole grid with exact positions, "
                                 "from a fresh run: not with --levels, --field, --mask-class, --gps-sigma or "
                                 "--resume", param_hint="--agents")
    if min(agents) < 1 or grid.moving:
        raise typer.BadParameter(f"--agents takes team sizes >= 1 on static targets (got {agents}, "
                                 f"motion {grid.motion})", param_hint="--agents")
    if init is None:
        sized = shipped_checkpoint(f"searchnet_{grid.motion}_{grid.distribution}_{grid.width}x{grid.height}")
        init = sized if sized.is_file() else shipped_checkpoint(f"searchnet_{grid.motion}_{grid.distribution}")
        if not init.is_file():
            init = shipped_checkpoint("searchnet_static_random")
    torch.set_num_threads(threads or 1)
    over = {k: v for k, v in (("episodes", episodes), ("epochs", epochs), ("beta0", beta0)) if v is not None}
    try:
        dc = TeamDaggerConfig(iterations=iterations, chunks=max(workers, 1), **over)
        mappo = {} if mappo_episodes is None else {"episodes": mappo_episodes}
        tc = TeamTrainConfig(dagger=dc, mappo_updates=mappo_updates, mappo=mappo, seed=seed, team_planes=team_planes,
                             **({"val_episodes": val_episodes} if val_episodes else {}))
        summary = train_team(out, [(grid, k) for k in dict.fromkeys(agents)], init, tc, workers, log=typer.echo)
    except (ValueError, CheckpointError) as e:
        raise typer.BadParameter(str(e), param_hint="--agents") from e
    typer.echo(f"{out / 'searchnet.pt'}: the best team search network ({summary['best']['stage']}, validation "
               f"makespan / team planner {summary['best']['score']:.4f}; evaluate: uavsearch eval --agents N "
               f"-p searchnet --checkpoint {out / 'searchnet.pt'})")


#: searchnet with levels: one-hot planes for L_max = 3 (GridConfig allows 1..3), so one network
#: serves every field of up to 3 levels
LEVEL_PLANES = 3


def _fields(field: Path | None, classes: list[str] | None, area: int, grid: GridConfig):
    """(the field file's grid, FieldSpec) for --field, (grid, FieldSpec) of random classes for
    --mask-class, None for neither; both is a usage error."""
    if field is None and not classes:
        return None
    if field is not None and classes:
        raise typer.BadParameter("give --field or --mask-class, not both", param_hint="--field")
    from policy.searchnet.fields import FieldSpec

    if field is not None:
        from .eval import _field_grid

        cfg, mask = _field_grid(field, grid)
        return cfg, FieldSpec.fixed(mask)
    try:
        return grid, FieldSpec(classes=tuple(classes or ()), area=area)
    except ValueError as e:
        raise typer.BadParameter(str(e), param_hint="--mask-class") from e


def _train_drqn(out: Path, episodes: int, seed: int, resume: bool, threads: int | None, grid: GridConfig) -> None:
    import torch

    from policy.drqn import DrqnConfig, train_drqn
    from policy.nn import CheckpointError

    if grid.motion != "static":
        raise typer.BadParameter("the DRQN baseline has 4 actions: static targets only", param_hint="--motion")
    torch.set_num_threads(threads or 1)
    try:
        path = train_drqn(DrqnConfig(episodes=episodes), grid, out, seed=seed, resume=resume)
    except CheckpointError as e:
        raise typer.BadParameter(str(e), param_hint="--resume") from e
    typer.echo(f"{path}: DRQN after {episodes} episodes (resume with --resume, more with a larger --episodes)")
