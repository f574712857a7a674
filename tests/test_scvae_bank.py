"""The S-CVAE's transition bank (:mod:`inbetween_jax.models.scvae.bank`) on real capture (the embedded CMU
clips): a bank transition's own keyframes give it back exactly, in any world placement; the warp; the distance
weights; the blend; the bank file and its errors; and the wiring into ``infer.sample_transitions``."""
from __future__ import annotations

import dataclasses
import json
import os
import shutil

import numpy as np
import pytest

from inbetween_jax.data import load_dataset, load_motions
from inbetween_jax.errors import UserError
from inbetween_jax.geometry.quaternion import quat_from_axis_angle, quat_mul, quat_rotate
from inbetween_jax.geometry.mirror import mirror_pose, rest_side_axis
from inbetween_jax.models.scvae.bank import (BANK_FILE, MIRROR_TAG, TransitionBank, bank_enabled, blend,
                                            knn_transition)
from inbetween_jax.train.run import RunError

L = 20


@pytest.fixture(scope="module")
def bank():
    motions = load_motions("embedded", "train")
    return TransitionBank.from_motions(motions, motions[0].skeleton.forward_axis(), stride=3)


def _bank_transition(bank, i):
    """Bank transition i of length L: its frames (L + 2, J, 4), (L + 2, 3) in the bank's world space."""
    frames = bank.index(L)[0]
    f = frames[i] + np.arange(L + 2)
    return bank.local_quats[f].astype(np.float64), bank.root_pos[f].astype(np.float64)


def _place(q, r, yaw, shift):
    """The same frames turned by ``yaw`` about +Y and moved by ``shift`` (a rigid motion of the world)."""
    rot = quat_from_axis_angle(np.array([0.0, 1.0, 0.0]), np.float64(yaw))
    q = q.copy()
    q[..., 0, :] = quat_mul(np.broadcast_to(rot, q[..., 0, :].shape), q[..., 0, :])
    return q, quat_rotate(np.broadcast_to(rot, r.shape[:-1] + (4,)), r) + shift


def _knn(bank, q, r, k=1, tau=0.0):
    return knn_transition(bank, q[None, 0], r[None, 0], q[None, -1], r[None, -1], L, k, tau)


def _shipped_copy(tmp_path, **model) -> str:
    """A copy of the shipped S-CVAE folder without its bank, its config's switches set to ``model`` (the sampled
    mode off, and not scaled by the gate, unless given)."""
    from inbetween_jax.shipped import shipped_dir
    src = shipped_dir("scvae")
    if src is None:
        pytest.skip("no shipped S-CVAE weights")
    run_dir = str(tmp_path / "scvae")
    shutil.copytree(src, run_dir, ignore=shutil.ignore_patterns(BANK_FILE))
    meta = json.load(open(os.path.join(run_dir, "run.json")))
    meta["config"]["model"].update({"bank_sample_weight": 0.0, "bank_sample_gated": False, **model})
    json.dump(meta, open(os.path.join(run_dir, "run.json"), "w"))
    return run_dir


def test_a_bank_transition_is_its_own_nearest_in_any_world_placement(bank):
    n = len(bank.index(L)[0])
    assert n > 100 and bank.index(L)[3].shape == (n, 2 * bank.num_joints * 3)
    for i in (0, n // 2, n - 1):
        q, r = _bank_transition(bank, i)
        for yaw, shift in ((0.0, 0.0), (2.1, np.array([150.0, 0.0, -80.0]))):
            pq, pr = _place(q, r, yaw, shift)
            kq, kr, dist = _knn(bank, pq, pr)
            assert dist[0] < 1e-3
            np.testing.assert_allclose(kr[0], pr[1:-1], atol=1e-3)
            dots = np.abs(np.sum(kq[0] * pq[1:-1], -1))
            assert dots.min() > 1 - 1e-5                          # the same rotations
            assert np.sum(kq[0, 0] * pq[0], -1).min() > 0         # signs follow the start keyframe


def test_the_warp_moves_each_frame_by_its_share_of_the_target_shift(bank):
    q, r = _bank_transition(bank, 40)
    delta = np.array([0.3, -0.2, 0.4])               # a few mm: the nearest transition stays the same
    moved = r.copy()
    moved[-1] += delta
    _, kr, dist = _knn(bank, q, moved)
    share = (np.arange(1, L + 1) / (L + 1))[:, None]
    np.testing.assert_allclose(kr[0], r[1:-1] + share * delta, atol=1e-3)
    assert 0 < dist[0] < 1.0


def test_sharp_distance_weights_keep_the_nearest_and_uniform_weights_average(bank):
    q, r = _bank_transition(bank, 75)
    q[-1, 5:] = quat_mul(quat_from_axis_angle(np.array([1.0, 0.0, 0.0]), np.float64(0.2)), q[-1, 5:])  # not in the bank
    one = _knn(bank, q, r, k=1)
    sharp = _knn(bank, q, r, k=8, tau=1e-6)
    flat = _knn(bank, q, r, k=8, tau=0.0)
    np.testing.assert_allclose(sharp[1], one[1], atol=1e-6)
    np.testing.assert_allclose(sharp[0], one[0], atol=1e-6)
    assert np.abs(flat[1] - one[1]).max() > 0.1                   # eight different transitions averaged


def test_blend_ends_and_middle():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(3, 2, 5, 4, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    r = rng.normal(size=(3, 2, 5, 3))
    bq = rng.normal(size=(2, 5, 4, 4))
    bq /= np.linalg.norm(bq, axis=-1, keepdims=True)
    br = rng.normal(size=(2, 5, 3))
    q0, r0 = blend(q, r, bq, br, 0.0)
    q1, r1 = blend(q, r, bq, br, 1.0)
    np.testing.assert_allclose(r0, r)
    np.testing.assert_allclose(r1, np.broadcast_to(br, r.shape))
    np.testing.assert_allclose(np.abs(np.sum(q0 * q, -1)), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.abs(np.sum(q1 * bq[None], -1)), 1.0, atol=1e-9)
    _, rh = blend(q, r, bq, br, 0.5)
    np.testing.assert_allclose(rh, (r + br[None]) / 2)


def test_bank_file_round_trip_and_errors(bank, tmp_path):
    path = str(tmp_path / BANK_FILE)
    bank.save(path)
    back = TransitionBank.load(path)
    assert back.names == bank.names and back.parents == bank.parents and back.stride == bank.stride
    np.testing.assert_array_equal(back.root_pos, bank.root_pos)
    assert np.abs(np.abs(np.sum(back.local_quats * bank.local_quats, -1)) - 1).max() < 1e-5   # float16 storage
    with pytest.raises(UserError, match="not a readable transition bank"):
        TransitionBank.load(str(tmp_path / "missing.npz"))
    np.savez(str(tmp_path / "bad.npz"), local_quats=np.zeros((4, 3)))
    with pytest.raises(UserError, match="bad.npz"):
        TransitionBank.load(str(tmp_path / "bad.npz"))
    for name, data in (("empty.npz", b""), ("cut.npz", open(path, "rb").read()[:200])):   # not zips / cut short
        (tmp_path / name).write_bytes(data)
        with pytest.raises(UserError, match=f"{name}: not a readable transition bank"):
            TransitionBank.load(str(tmp_path / name))
    with pytest.raises(UserError, match="no clip holds"):
        back.index(10 ** 6)


def test_switches_and_the_bank_in_sample_transitions(bank, tmp_path):
    """A copy of the shipped S-CVAE: without bank.npz its load fails in one line; with ``bank_weight`` 1 its
    samples are the bank's transitions; a mismatched skeleton is refused."""
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.train.run import load_run
    run_dir = _shipped_copy(tmp_path, bank_k=4, bank_weight=1.0, bank_tau=0.5)
    with pytest.raises(RunError, match="needs bank.npz, which is missing"):
        infer.load(load_run(run_dir))
    bank.save(os.path.join(run_dir, BANK_FILE))
    trained = infer.load(load_run(run_dir))
    assert bank_enabled(trained.cfg.model) and trained.bank.num_frames == bank.num_frames
    wins = load_dataset("embedded", "benchmark").take(slice(0, 3))
    s = infer.sample_transitions(trained.cfg.model, trained.state, wins, 10, L, 2, bank=trained.bank)
    kq, kr, _ = knn_transition(trained.bank, wins.local_quats[:, 9], wins.root_pos[:, 9], wins.local_quats[:, 10 + L],
                               wins.root_pos[:, 10 + L], L, 4, 0.5)
    np.testing.assert_allclose(s["r"], np.broadcast_to(kr, s["r"].shape), atol=1e-5)
    net = infer.sample_transitions(trained.cfg.model, trained.state, wins, 10, L, 2)
    assert np.abs(net["r"] - s["r"]).max() > 0.1                     # without the bank: the network's own
    start = {"q": wins.local_quats[0, 9], "r": wins.root_pos[0, 9], "c": wins.contacts[0, 9]}
    end = {"q": wins.local_quats[0, 10 + L], "r": wins.root_pos[0, 10 + L], "c": wins.contacts[0, 10 + L]}
    out = infer.infill_between(trained, wins.skeleton, start, end, L, 2)    # users' keyframes: the same bank
    np.testing.assert_allclose(out["r"][:, 1:-1], np.broadcast_to(kr[0], (2, L, 3)), atol=1e-4)
    small = dataclasses.replace(bank, local_quats=bank.local_quats[:, :5], offsets=bank.offsets[:5],
                                parents=bank.parents[:5])
    small.save(os.path.join(run_dir, BANK_FILE))
    with pytest.raises(RunError, match="joints"):
        infer.load(load_run(run_dir))


def test_build_bank_command_writes_the_bank_and_the_switches(tmp_path, capsys):
    """``inbetween build-bank``: one-line errors that write nothing, the bank and its switches in run.json."""
    from inbetween_jax.cli import main
    from inbetween_jax.shipped import shipped_dir

    class script:                                  # the command line as the tests below call it
        main = staticmethod(lambda argv: main(["build-bank"] + argv))
    run_dir = _shipped_copy(tmp_path)
    assert script.main([run_dir, "--source", "embedded", "--set", "model.texture_gain=1"]) == 2
    assert "not a bank switch" in capsys.readouterr().err and not os.path.exists(os.path.join(run_dir, BANK_FILE))
    assert script.main([run_dir, "--source", "embedded", "--split", "train", "--set", "model.bank_k=8",
                        "--set", "model.bank_weight=0.5"]) == 0
    meta = json.load(open(os.path.join(run_dir, "run.json")))
    assert meta["config"]["model"]["bank_k"] == 8 and meta["config"]["model"]["bank_weight"] == 0.5
    bank = TransitionBank.load(os.path.join(run_dir, BANK_FILE))
    assert bank.num_frames == meta["bank"]["frames"] and len(bank.names) == len(load_motions("embedded", "train"))
    assert meta["bank"]["mirror"] is False
    inter = str(tmp_path / "interaction")          # the mirror is an S-CVAE bank's only
    shutil.copytree(shipped_dir("interaction"), inter, ignore=shutil.ignore_patterns("bank.npz"))
    assert script.main([inter, "--mirror"]) == 2 and "S-CVAE banks only" in capsys.readouterr().err
    assert not os.path.exists(os.path.join(inter, "bank.npz"))
    assert script.main([run_dir, "--source", "embedded", "--split", "train", "--mirror"]) == 0
    meta = json.load(open(os.path.join(run_dir, "run.json")))
    mirrored = TransitionBank.load(os.path.join(run_dir, BANK_FILE))
    assert meta["bank"]["mirror"] is True and meta["config"]["model"]["bank_k"] == 8     # switches kept
    assert mirrored.num_frames == 2 * bank.num_frames and mirrored.names[len(bank.names)].endswith(MIRROR_TAG)
    assert script.main([run_dir, "--source", "embedded", "--split", "fit"]) == 0       # the run's own fit split:
    meta = json.load(open(os.path.join(run_dir, "run.json")))                             # whole subjects held out
    assert meta["config"]["train"]["split"] == "fit-subjects" and meta["bank"]["split"] == "fit-subjects"
    held_out = {os.path.basename(m.source) for m in load_motions("embedded", "val-subjects")}
    assert held_out and not held_out & set(TransitionBank.load(os.path.join(run_dir, BANK_FILE)).names)


def test_transitions_that_spin_are_not_candidates():
    """Two keyframes cannot tell a full spin from none: a clip turned about +Y by a growing angle (one full turn
    every 60 frames) keeps the unturned clip's candidates only where the extra turn stays under half a turn."""
    from inbetween_jax.models.scvae.bank import MAX_TURN
    m = load_motions("embedded", "train")[0]
    spin = 2 * np.pi * np.arange(m.num_frames) / 60.0
    up = np.zeros((m.num_frames, 3))
    up[:, 1] = 1.0
    rot = quat_from_axis_angle(up, spin)
    q = m.local_quats.astype(np.float64).copy()
    q[:, 0] = quat_mul(rot, q[:, 0])
    spun = dataclasses.replace(m, local_quats=q, local_pos=m.local_pos.copy())
    spun.local_pos[:, 0] = quat_rotate(rot, m.root_pos.astype(np.float64))
    fa = m.skeleton.forward_axis()
    plain_bank = TransitionBank.from_motions([m], fa, stride=1)
    spun_bank = TransitionBank.from_motions([spun], fa, stride=1)
    for length in (5, 20, 28):
        frames = plain_bank.index(length)[0]
        extra = spun_bank._turned(frames, length + 1) - plain_bank._turned(frames, length + 1)
        np.testing.assert_allclose(extra, 2 * np.pi * (length + 1) / 60.0, atol=1e-6)
        kept = set(spun_bank.index(length)[0])
        expect = set(frames[np.abs(spun_bank._turned(frames, length + 1)) <= MAX_TURN])
        assert kept == expect
    np.testing.assert_array_equal(spun_bank.index(5)[0], plain_bank.index(5)[0])    # 0.6 rad more: all kept
    with pytest.raises(UserError, match="turns less than half a turn"):
        spun_bank.index(40)                                           # every 41-frame span turns 4.3 rad or more


def test_a_clip_left_out_is_never_retrieved(bank):
    """``exclude`` (training with ``model.bank_base``: a window never retrieves its own file): a bank transition's
    own keyframes then find a transition of another clip, never one of their own."""
    frames = bank.index(L)[0]
    clip_of_frame = np.searchsorted(bank.clip_starts, frames, side="right") - 1
    for i in (0, len(frames) // 2):
        q, r = _bank_transition(bank, i)
        own = int(clip_of_frame[i])
        assert _knn(bank, q, r)[2][0] < 1e-3
        _, _, dist = knn_transition(bank, q[None, 0], r[None, 0], q[None, -1], r[None, -1], L, 1, 0.0,
                                    exclude=np.array([own]))
        assert dist[0] > 1e-2
    names = [f"{n.rsplit('.', 1)[0]}@7" for n in bank.names]
    assert list(bank.clip_of([n.split("@")[0] for n in names])) == list(range(len(bank.names)))
    assert bank.clip_of(["not_a_clip"])[0] == -1


def test_bank_base_path_holds_the_keyframes_and_the_bank_transition(bank):
    from inbetween_jax.models.scvae.bank import knn_base_path
    q, r = _bank_transition(bank, 5)
    q, r = _place(q, r, 0.7, np.array([30.0, 0.0, 12.0]))
    tq, tr = q[None, -1], r[None, -1]
    bq, br = knn_base_path(bank, q[None, 0], r[None, 0], tq, tr, L + 1, L + 6, 4, 0.5)
    assert bq.shape == (1, L + 7, bank.num_joints, 4) and br.shape == (1, L + 7, 3)
    kq, kr, _ = knn_transition(bank, q[None, 0], r[None, 0], tq, tr, L, 4, 0.5)
    np.testing.assert_allclose(br[0, 1:L + 1], kr[0], atol=1e-4)
    np.testing.assert_allclose(np.abs(np.sum(bq[0, 1:L + 1] * kq[0], -1)), 1.0, atol=1e-5)
    np.testing.assert_allclose(br[0, 0], r[0], atol=1e-4)
    np.testing.assert_allclose(br[0, L + 1:], np.broadcast_to(tr, (6, 3)), atol=1e-4)
    np.testing.assert_allclose(np.abs(np.sum(bq[0, L + 1:] * tq, -1)), 1.0, atol=1e-5)
    assert np.sum(bq[0, :-1] * bq[0, 1:], -1).min() > 0                    # signs continuous in time


def test_bank_base_training_writes_its_bank_and_an_untrained_model_returns_the_bank(tmp_path):
    """``model.bank_base``: training keeps its bank in the run folder; no window's base comes from its own file;
    the untrained residual model (zero-initialised head) returns the bank's transition; without its bank the
    model is refused in one line."""
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.models.scvae import train as T
    from inbetween_jax.runner import build_config, train_model
    from inbetween_jax.train.run import load_run
    over = ["model.residual=true", "model.bank_base=true", "model.bank_k=4", "model.bank_tau=0.5"]
    cfg = build_config("scvae", "tiny", over)
    data = T.load_data(cfg, "embedded", "train")
    own = data.bank.clip_of([n.split("@")[0] for n in data.names])
    assert own.min() >= 0
    batch = T.batch_fn_factory(data, cfg)(0, __import__("jax").random.key(3))
    n = int(batch["length"])
    assert batch["base_q"].shape == batch["q"].shape and batch["base_r"].shape == batch["r"].shape
    np.testing.assert_allclose(batch["base_r"][:, [0, n]], batch["r"][:, [0, n]], atol=1e-4)
    assert np.abs(batch["base_r"][:, 1:n] - batch["r"][:, 1:n]).max(axis=(1, 2)).min() > 1e-3   # not itself
    with pytest.raises(ValueError, match="model.bank_base needs"):
        T.load_data(build_config("scvae", "tiny", ["model.bank_base=true", "model.bank_k=4"]), "embedded", "train")
    run_dir = str(tmp_path / "run")
    train_model("scvae", "tiny", over + ["train.num_steps=0"], source="embedded", run_dir=run_dir, log=None)
    trained = infer.load(load_run(run_dir))
    assert trained.bank.num_frames == data.bank.num_frames
    wins = load_dataset("embedded", "benchmark").take(slice(0, 3))
    s = infer.sample_transitions(trained.cfg.model, trained.state, wins, 10, 8, 2, bank=trained.bank)
    kq, kr = infer.bank_transitions(trained.bank, trained.cfg.model, wins, 10, 8)
    np.testing.assert_allclose(s["r"], np.broadcast_to(kr, s["r"].shape), atol=1e-3)
    np.testing.assert_allclose(np.abs(np.sum(s["q"] * kq[None], -1)), 1.0, atol=1e-4)
    start = {"q": wins.local_quats[0, 9], "r": wins.root_pos[0, 9], "c": wins.contacts[0, 9]}
    end = {"q": wins.local_quats[0, 18], "r": wins.root_pos[0, 18], "c": wins.contacts[0, 18]}
    out = infer.infill_between(trained, wins.skeleton, start, end, 8, 2)      # users' keyframes: the same
    np.testing.assert_allclose(out["r"][:, 1:-1], np.broadcast_to(kr[0], (2, 8, 3)), atol=1e-3)
    with pytest.raises(ValueError, match="pass its bank"):
        infer.sample_transitions(trained.cfg.model, trained.state, wins, 10, 8, 2)
    os.remove(os.path.join(run_dir, BANK_FILE))
    with pytest.raises(RunError, match="needs bank.npz"):
        infer.load(load_run(run_dir))


def test_a_mirrored_bank_holds_each_clip_and_its_mirror_image():
    """``mirror=True``: the mirror image of a bank transition is found in the bank exactly (it is one of the
    mirrored clips), and a query left out of its own clip is left out of that clip's mirror image too."""
    motions = load_motions("embedded", "train")[:6]
    fa = motions[0].skeleton.forward_axis()
    bank = TransitionBank.from_motions(motions, fa, stride=3, mirror=True)
    c = len(motions)
    assert len(bank.names) == 2 * c and bank.names[c].endswith(MIRROR_TAG)
    assert bank.num_frames == 2 * sum(m.num_frames for m in motions)
    assert list(bank.source_clips) == list(range(c)) * 2
    assert list(bank.clip_of([bank.names[0], bank.names[c]])) == [0, c]
    q, r = _bank_transition(TransitionBank.from_motions(motions, fa, stride=3), 5)
    twin = motions[0].skeleton.mirror_map()
    mq, mr = mirror_pose(q, r, twin, rest_side_axis(motions[0].skeleton.offsets, twin))
    kq, kr, dist = _knn(bank, mq, mr)
    assert dist[0] < 1e-3
    np.testing.assert_allclose(kr[0], mr[1:-1], atol=1e-3)
    assert np.abs(np.sum(kq[0] * mq[1:-1], -1)).min() > 1 - 1e-5
    own = int(np.searchsorted(bank.clip_starts, bank.index(L)[0][5], side="right") - 1)
    _, _, dist = knn_transition(bank, mq[None, 0], mr[None, 0], mq[None, -1], mr[None, -1], L, 1, 0.0,
                                exclude=np.array([own]))
    assert dist[0] > 1e-2
    flat = dataclasses.replace(motions[0].skeleton, names=tuple(f"j{i}" for i in range(len(twin))))
    with pytest.raises(UserError, match="mirror"):
        TransitionBank.from_motions([dataclasses.replace(motions[0], skeleton=flat)], fa, mirror=True)


def test_each_neighbour_and_the_sampled_mode(bank, tmp_path):
    """``each``: the nearest of ``each`` is the k = 1 transition, and the k differ; the sampled mode keeps sample 0
    and moves sample s >= 1 toward the s-th nearest (weight 1: exactly it), in ``sample_transitions`` (after the
    gate) and in ``infill_between`` alike."""
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.train.run import load_run
    q, r = _bank_transition(bank, 75)
    q[-1, 5:] = quat_mul(quat_from_axis_angle(np.array([1.0, 0.0, 0.0]), np.float64(0.2)), q[-1, 5:])
    one = _knn(bank, q, r, k=1)
    eq, er, _ = knn_transition(bank, q[None, 0], r[None, 0], q[None, -1], r[None, -1], L, 3, each=True)
    assert eq.shape == (1, 3, L, bank.num_joints, 4) and er.shape == (1, 3, L, 3)
    np.testing.assert_allclose(er[:, 0], one[1], atol=1e-6)
    np.testing.assert_allclose(np.abs(np.sum(eq[:, 0] * one[0], -1)), 1.0, atol=1e-6)
    assert np.abs(er[:, 1] - er[:, 0]).max() > 0.1 and np.abs(er[:, 2] - er[:, 1]).max() > 0.1
    run_dir = _shipped_copy(tmp_path, bank_sample_weight=1.0, timing_spread=0.0,
                            timing_spread_fallback=0.0)                          # the bank part alone
    with pytest.raises(RunError, match="needs bank.npz, which is missing"):
        infer.load(load_run(run_dir))
    bank.save(os.path.join(run_dir, BANK_FILE))
    trained = infer.load(load_run(run_dir))
    wins = load_dataset("embedded", "benchmark").take(slice(0, 3))
    args = (trained.cfg.model, trained.state, wins, 10, L, 3)
    gate = dict(gate=trained.gate, forward_axis=trained.extra.get("forward_axis"))
    plain = infer.sample_transitions(*args, sampled=False, **gate)
    s = infer.sample_transitions(*args, bank=trained.bank, **gate)
    np.testing.assert_allclose(s["r"][0], plain["r"][0], atol=1e-6)                 # sample 0: the gated fill
    k0, k1 = 9, 10 + L
    eq, er, _ = knn_transition(trained.bank, wins.local_quats[:, k0], wins.root_pos[:, k0], wins.local_quats[:, k1],
                               wins.root_pos[:, k1], L, 2, each=True)
    for j in (0, 1):
        np.testing.assert_allclose(s["r"][1 + j], er[:, j], atol=1e-5)
    start = {"q": wins.local_quats[0, k0], "r": wins.root_pos[0, k0], "c": wins.contacts[0, k0]}
    end = {"q": wins.local_quats[0, k1], "r": wins.root_pos[0, k1], "c": wins.contacts[0, k1]}
    out = infer.infill_between(trained, wins.skeleton, start, end, L, 3)
    np.testing.assert_allclose(out["r"][1:, 1:-1], er[0], atol=1e-4)
    assert np.abs(out["r"][0, 1:-1] - er[0, 0]).max() > 0.1                         # sample 0: not the bank's


def test_gated_sampled_mode_moves_each_sample_by_the_gates_weight(bank, tmp_path):
    """``model.bank_sample_gated``: sample s >= 1 moves toward the s-th nearest transition by the sampled-mode
    weight times the gate's weight per window, so where the gate closes (the test subjects' motion in place) the
    samples stay the fill."""
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.train.run import load_run
    run_dir = _shipped_copy(tmp_path, bank_sample_weight=1.0, bank_sample_gated=True, timing_spread=0.0,
                            timing_spread_fallback=0.0)
    bank.save(os.path.join(run_dir, BANK_FILE))
    trained = infer.load(load_run(run_dir))
    wins = load_dataset("embedded", "benchmark").take(slice(0, 12))
    args = (trained.cfg.model, trained.state, wins, 10, L, 3)
    gate = dict(gate=trained.gate, forward_axis=trained.extra.get("forward_axis"))
    plain = infer.sample_transitions(*args, sampled=False, **gate)          # each sample's gated fill
    s = infer.sample_transitions(*args, bank=trained.bank, **gate)
    w = s["gate_weight"]
    assert (w < 0.5).any()
    k0, k1 = 9, 10 + L
    _, er, _ = knn_transition(trained.bank, wins.local_quats[:, k0], wins.root_pos[:, k0], wins.local_quats[:, k1],
                              wins.root_pos[:, k1], L, 2, each=True)
    for j in (0, 1):
        expected = plain["r"][1 + j] + w[:, None, None] * (er[:, j] - plain["r"][1 + j])
        np.testing.assert_allclose(s["r"][1 + j], expected, atol=1e-5)
    closed = w == 0.0
    assert closed.any()
    np.testing.assert_allclose(s["q"][:, closed], plain["q"][:, closed], atol=1e-6)
