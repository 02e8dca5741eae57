"""DAgger relabelling: the aggregated data are the student's own states, labelled with the
teacher's action in each of them (checked against an independent replay)."""

import numpy as np
import torch

from policy.base import observe
from policy.baselines.registry import make_policy
from policy.belief import BELIEF_CHANNELS
from policy.searchnet import SearchNet, SearchNetConfig, SearchNetPolicy
from policy.searchnet.dagger import DaggerConfig, rollout_tasks
from policy.searchnet.rollout import collect
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes

GRID = GridConfig(width=6, height=6, n_targets=3)


def _student() -> SearchNet:
    torch.manual_seed(3)
    return SearchNet(SearchNetConfig(BELIEF_CHANNELS)).eval()


def test_aggregated_labels_are_the_teachers_actions_on_the_students_states() -> None:
    model = _student()
    dc = DaggerConfig(episodes=12, chunks=1, beta0=0.0)  # beta 0 after iteration 0: the student drives alone
    (task,) = rollout_tasks(dc, GRID, 1, model, None)
    assert task.beta == 0.0 and task.seed >= 1_000_000
    data = collect(task)

    # independent replay: the student drives, a fresh teacher is asked at every state it reaches
    ep = sample_episodes(GRID, task.episodes, task.seed)
    world = BatchGridWorld(ep, task.seed)
    student, teacher = SearchNetPolicy(model), make_policy("belief", GRID)
    student.reset(GRID, len(ep), task.seed)
    teacher.reset(GRID, len(ep), task.seed)
    pos, labels, driven = [], [], []
    for _ in range(task.max_steps):
        if world.done.all():
            break
        obs = observe(world)
        want = teacher.act(obs)
        mine = student.act(obs)
        pos.append(obs.positions[obs.active])
        labels.append(want[obs.active])
        driven.append(mine[obs.active])
        world.step(mine)
    pos, labels, driven = np.concatenate(pos), np.concatenate(labels), np.concatenate(driven)
    np.testing.assert_array_equal(data["positions"], pos)
    np.testing.assert_array_equal(data["labels"], labels)
    np.testing.assert_array_equal(data["moves"], world.t)
    # meaningful: an untrained student does not act as the teacher, so these are not the teacher's states
    assert (driven != labels).mean() > 0.2


def test_beta_one_is_the_teacher_driving_and_the_schedule_decays() -> None:
    dc = DaggerConfig(episodes=8, chunks=2, beta0=1.0, beta_decay=0.5)
    assert [dc.beta(i) for i in range(3)] == [1.0, 0.5, 0.25]
    tasks = rollout_tasks(dc, GRID, 0, None, None)
    assert [t.episodes for t in tasks] == [4, 4] and len({t.seed for t in tasks}) == 2
    data = collect(tasks[0])
    teacher = make_policy("belief", GRID)
    ep = sample_episodes(GRID, 4, tasks[0].seed)
    teacher.reset(GRID, 4, tasks[0].seed)
    world = BatchGridWorld(ep, tasks[0].seed)
    while not world.done.all():
        world.step(teacher.act(observe(world)))
    np.testing.assert_array_equal(data["moves"], world.t)
    assert data["planes"].shape[1:] == (BELIEF_CHANNELS, 6, 6)
    assert len(data["labels"]) == int(world.t.sum())
