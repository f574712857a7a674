"""Checkpoint selection on the validation split: the best-scoring step is recorded and loaded by default."""
import json
import os

from inbetween_jax.train.run import load_run, write_run
from inbetween_jax.train.select import SELECTION_FILE, select_checkpoint, selected_step


def _fake_run(tmp_path, steps):
    run_dir = str(tmp_path / "run")
    write_run(run_dir, model="scvae", preset="tiny", overrides=[], config={"train": {"num_steps": 9}})
    for s in steps:
        os.makedirs(os.path.join(run_dir, "checkpoints", str(s)))
        open(os.path.join(run_dir, "checkpoints", str(s), "x"), "w").close()
    return run_dir


def test_selection_picks_the_lowest_validation_score_and_load_run_uses_it(tmp_path):
    run_dir = _fake_run(tmp_path, [0, 250, 500, 750])
    assert load_run(run_dir).step == 750                       # no selection: the latest
    scores = {250: 0.9, 500: 0.7, 750: 0.8}
    seen = []
    out = select_checkpoint(run_dir, "cmu", lambda r: seen.append(r.step) or scores[r.step], "val L2P", log=None)
    assert seen == [250, 500, 750]                              # step 0 (the untrained state) is not a candidate
    assert out["step"] == 500 and selected_step(run_dir) == 500
    assert load_run(run_dir).step == 500 and load_run(run_dir, 750).step == 750
    rec = json.load(open(os.path.join(run_dir, SELECTION_FILE)))
    assert rec["split"] == "val" and rec["scores"]["750"] == 0.8


def test_a_selection_whose_checkpoint_is_gone_falls_back_to_the_latest(tmp_path):
    run_dir = _fake_run(tmp_path, [250, 500])
    with open(os.path.join(run_dir, SELECTION_FILE), "w") as f:
        json.dump({"step": 100}, f)
    assert load_run(run_dir).step == 500


def test_a_second_selection_scores_only_new_checkpoints(tmp_path):
    run_dir = _fake_run(tmp_path, [250, 500])
    select_checkpoint(run_dir, "cmu", lambda r: {250: 0.5, 500: 0.6}[r.step], "val L2P", log=None)
    os.makedirs(os.path.join(run_dir, "checkpoints", "750"))
    open(os.path.join(run_dir, "checkpoints", "750", "x"), "w").close()
    seen = []
    out = select_checkpoint(run_dir, "cmu", lambda r: seen.append(r.step) or 0.4, "val L2P", log=None)
    assert seen == [750] and out["step"] == 750


def test_an_unreadable_checkpoint_is_skipped_not_fatal(tmp_path):
    from inbetween_jax.train.run import RunError
    run_dir = _fake_run(tmp_path, [250, 500])

    def score(r):
        if r.step == 500:
            raise RunError("checkpoints/500: cannot restore the checkpoint (missing metadata)")
        return 1.0

    out = select_checkpoint(run_dir, "cmu", score, "val L2P", log=None)
    assert out["step"] == 250 and list(out["scores"]) == ["250"]


def test_checkpoints_record_training_time_across_a_resume_and_time_to_score_reads_it(tmp_path):
    """``stop_at`` ends a run early with its schedule unchanged; the resumed run's checkpoints carry on the training
    wall time; :func:`time_to_score` reports the first checkpoint at or below a target with that time;
    :func:`checkpoint_wall_times` every checkpoint's."""
    from inbetween_jax.runner import train_model
    from inbetween_jax.train.checkpoint import Checkpointer
    from inbetween_jax.train.select import checkpoint_wall_times, time_to_score
    run_dir = str(tmp_path / "cae")
    args = ("cae", "tiny", ["train.num_steps=6", "train.ckpt_every=2", "train.log_every=2"], "embedded", run_dir)
    train_model(*args, progress=False, log=None, stop_at=4)
    with Checkpointer(os.path.join(run_dir, "checkpoints"), max_to_keep=None) as ck:
        assert ck.all_steps()[-1] == 4
        first = [ck.restore_extra(s)["train_wall_s"] for s in (2, 4)]
    train_model(*args, progress=False, log=None)                                # resumes to step 6
    with Checkpointer(os.path.join(run_dir, "checkpoints"), max_to_keep=None) as ck:
        walls = [ck.restore_extra(s)["train_wall_s"] for s in (2, 4, 6)]
    assert walls[:2] == first and 0 < walls[0] <= walls[1] <= walls[2]
    assert json.load(open(os.path.join(run_dir, "run.json")))["history"][0]["steps"] == 4
    selection = {"scores": {"2": 0.9, "4": 0.7, "6": 0.6}}
    out = time_to_score(run_dir, selection, 0.75)
    assert (out["step"], out["score"], out["train_wall_s"]) == (4, 0.7, walls[1])
    assert time_to_score(run_dir, selection, 0.5) == {"target": 0.5, "step": None, "score": None,
                                                      "train_wall_s": None}
    assert checkpoint_wall_times(run_dir, selection["scores"]) == {2: walls[0], 4: walls[1], 6: walls[2]}
