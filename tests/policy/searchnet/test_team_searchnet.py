"""The decentralised team searchnet (issue 29): one agent decides as today's searchnet, the
teammates' planes, and a tiny DAgger run from the team planner that trains and flies a
6 x 6 / 2-agent world without a conflict; the CLI's train and eval with --agents."""

from __future__ import annotations

import json

import numpy as np
import torch
from typer.testing import CliRunner

from missions.cli import app
from policy.baselines.registry import make_policy
from policy.evaluation import evaluate
from policy.nn import shipped_checkpoint
from policy.searchnet.checkpoint import load_searchnet
from policy.searchnet.encode import egocentric_np
from policy.searchnet.team import TeamSearchNet, teammates_planes, widen_for_team
from policy.searchnet.teamdagger import TeamDaggerConfig
from policy.searchnet.teamtrain import TeamTrainConfig, train_team
from policy.team import evaluate_team, make_team_policy
from policy.team.base import team_observe
from sim.gridworld import GridConfig, sample_episodes
from sim.gridworld.team import TeamGridWorld, team_starts

SMALL = GridConfig(width=6, height=6, n_targets=2)


def test_one_agent_with_a_single_agent_checkpoint_is_todays_searchnet_exactly():
    cfg, ck = GridConfig(), shipped_checkpoint("searchnet_static_random")
    single = evaluate(make_policy("searchnet", cfg, checkpoint=ck), cfg, 30, 4, progress=False)
    team = evaluate_team(make_team_policy("searchnet", cfg=cfg, checkpoint=ck), cfg, 30, 4, 1, progress=False)
    assert np.array_equal(single.moves, team.makespan)
    assert np.array_equal(single.find_moves, team.find_moves)


def test_widened_network_decides_as_before_and_the_planes_say_where_teammates_are():
    model, _ = load_searchnet(shipped_checkpoint("searchnet_static_random"))
    rng = np.random.default_rng(0)
    planes = rng.random((3, model.cfg.in_channels, 6, 6)).astype(np.float32)
    pos = np.array([[0, 0], [5, 2], [3, 3]])
    for k in (1, 2):
        wide = widen_for_team(model, k)
        extra = rng.random((3, k, 6, 6)).astype(np.float32)  # any teammates: zero weights at first
        with torch.no_grad():
            a = model(torch.from_numpy(egocentric_np(planes, pos)))
            b = wide(torch.from_numpy(egocentric_np(np.concatenate([planes, extra], axis=1), pos)))
        assert torch.allclose(a, b, atol=1e-5)
    tp = teammates_planes(np.array([[[0, 0], [2, 0], [5, 5]]]), 6, 6, planes=2)  # (1, 3, 2, 6, 6)
    assert tp[0, 0, 0].sum() == 2 and tp[0, 0, 0, 0, 2] == 1 and tp[0, 0, 0, 5, 5] == 1 and tp[0, 0, 0, 0, 0] == 0
    assert tp[0, 0, 1, 0, 0] == 0 and tp[0, 0, 1, 0, 3] == 1 and tp[0, 0, 1, 5, 4] == 1  # nearer: agent 1, 2


def test_tiny_team_dagger_trains_and_flies_without_conflicts(tmp_path):
    torch.set_num_threads(1)
    init = shipped_checkpoint("searchnet_static_random")
    tc = TeamTrainConfig(dagger=TeamDaggerConfig(iterations=2, episodes=4, epochs=1, beta0=0.5), val_episodes=4,
                         team_planes=2, mappo_updates=1, mappo={"episodes": 4, "critic_warmup": 0, "epochs": 1})
    summary = train_team(tmp_path, [(SMALL, 2)], init, tc, log=lambda *_: None)
    assert [h["stage"] for h in summary["history"]] == ["init", "dagger", "dagger", "mappo"]
    assert all(h["new_states"] > 0 and 0 <= h["train_acc"] <= 1 for h in summary["history"][1:3])
    assert summary["history"][3]["6x6x2_kept"] > 0.5  # separation replaced few sampled moves
    pol = make_team_policy("searchnet", cfg=SMALL, checkpoint=tmp_path / "searchnet.pt")
    assert isinstance(pol, TeamSearchNet) and pol.model.cfg.team_planes == 2
    ep = sample_episodes(SMALL, 20, 8)
    world = TeamGridWorld(ep, team_starts(ep, 2), 8)
    pol.reset(SMALL, 20, 2, 8)
    while not world.done.all():
        a = pol.act(team_observe(world))
        world.step(a)
    tr = world.trajectories()  # (n, T, N, 2): never a shared cell, never a swap
    assert not np.all(tr[:, :, 0] == tr[:, :, 1], axis=-1).any()
    swap = np.all(tr[:, 1:, 0] == tr[:, :-1, 1], axis=-1) & np.all(tr[:, 1:, 1] == tr[:, :-1, 0], axis=-1)
    assert not swap.any() and world.blocked.sum() == 0 and world.success.all()


def test_cli_train_and_eval_with_agents(tmp_path):
    r = CliRunner().invoke(app, ["train", "--model", "searchnet", "--agents", "2", "--width", "6", "--height", "6",
                                 "--targets", "2", "--dagger-iterations", "1", "--dagger-episodes", "4",
                                 "--val-episodes", "4", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    ck = tmp_path / "searchnet.pt"
    r = CliRunner().invoke(app, ["eval", "--agents", "2", "-p", "searchnet", "-p", "belief", "--checkpoint", str(ck),
                                 "--width", "6", "--height", "6", "--targets", "2", "--episodes", "10", "--json"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.output)
    assert doc["checkpoint"] == str(ck) and doc["policies"]["searchnet"]["blocked_mean"] == 0.0
    r = CliRunner().invoke(app, ["train", "--model", "drqn", "--agents", "2", "--out", str(tmp_path / "x")])
    assert r.exit_code != 0 and "--agents" in r.output
