"""Foot lift-offs (inbetween_jax/metrics/steps.py): real CMU walks step, Slerp between their keyframes glides,
and a hand-made gait gives the count a brute-force loop gives."""
import numpy as np

from inbetween_jax.baselines import interpolate_transition
from inbetween_jax.data import load_dataset
from inbetween_jax.data.activities import activity_group
from inbetween_jax.geometry import forward_kinematics, local_positions
from inbetween_jax.metrics.steps import lift_offs


def test_lift_offs_count_a_made_up_gait_like_a_loop():
    t = 40
    pos = np.zeros((t, 3, 3))
    pos[:, 0, 0] = np.arange(t) * 4.0                    # the root walks 4 cm per frame
    for j, phase in ((1, 0), (2, 10)):                   # each foot: 10 frames still, 10 frames at 8 cm / frame
        x, xs = 0.0, []
        for i in range(t):
            x += 8.0 if (i + phase) % 20 >= 10 else 0.0
            xs.append(x)
        pos[:, j, 0] = xs
    speed = np.abs(np.diff(pos[:, 1:, 0], axis=0))
    stance = speed < 2.0
    brute = sum(int(stance[i, f] and not stance[i + 1, f]) for i in range(t - 2) for f in range(2))
    assert float(lift_offs(pos, (1, 2))) == brute >= 3


def test_captured_walks_step_and_slerp_between_their_keyframes_glides():
    w = load_dataset("cmu", "val-subjects", window=65, offset=20)
    walks = w.take(np.array([i for i, n in enumerate(w.seq_names) if activity_group(n.split("@")[0]) == "walk"]))
    assert len(walks) >= 10
    feet = walks.skeleton.foot_joints()
    ankles = (feet[0], feet[2])
    lo, n = 10, 50
    _, gt = walks.global_pose()
    q, r = interpolate_transition(walks.local_quats.astype(np.float64), walks.root_pos.astype(np.float64), lo, n)
    _, sl = forward_kinematics(q, local_positions(r, walks.skeleton.offsets), walks.parents)
    real = np.asarray(lift_offs(np.asarray(gt)[:, lo - 1:lo + n + 1], ankles))
    glide = np.asarray(lift_offs(np.concatenate([np.asarray(gt)[:, lo - 1:lo], sl, np.asarray(gt)[:, lo + n:lo + n + 1]],
                                                1), ankles))
    assert np.median(real) >= 2 and np.mean(glide) < 0.5 * np.mean(real)
