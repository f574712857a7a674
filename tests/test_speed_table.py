"""The speed section's training-step comparison (inbetween_jax.evaluation.speed) without running a model: side-by-side
timing in rotating rounds, a torch.compile backend that fails is recorded and the next one used, and the table's
cells (ratios; "not installed" without torch)."""
import pytest

from inbetween_jax.evaluation import speed


def _record(cae_row, scvae_row, **extra):
    return {"jax": "0", "device": "cpu", "cpus": 2, "peak_gflops": 100.0, **extra,
            "scvae": {"widths": {"paper": scvae_row}, "infer_10_gflop": 19.0, "infer_10_ms": 400.0, "infer_batch": 640,
                      "infer_transitions_s": 100.0, "jax_gflops": 50.0, "step_gflop": 200.0, "compile_infer": (2, 1)},
            "cae": {"frames": 1927, "ms_per_frame": 0.07, "ms": 140.0, "compile": (0.5, 0.1),
                    "train": {"improved": cae_row}},
            "interaction": {"ms": 1.1, "compile": (1.0, 0.2)}}


def test_side_by_side_rotates_and_times_every_call():
    order = []
    fns = {n: (lambda n=n: order.append(n)) for n in ("a", "b", "c")}
    times = speed._side_by_side(fns, reps=3, warmup=1)
    assert order == ["a", "b", "c", "a", "b", "c", "b", "c", "a", "c", "a", "b"]
    assert {n: len(t) for n, t in times.items()} == {"a": 3, "b": 3, "c": 3}


def test_a_backend_that_fails_is_recorded_and_the_next_one_used():
    def make(backend):
        if backend == "inductor":
            def broken():
                raise RuntimeError("no C++ compiler\nmore")
            return broken
        return lambda: 1.0

    out = {}
    speed._compare_steps(out, lambda: 1.0, make, reps=2)
    assert len(out["calls_ms"]["jax"]) == 5                              # at least 5 rounds
    assert out["torch_compile_tries"]["inductor"] == {"error": "RuntimeError: no C++ compiler"}
    assert out["torch_compile_backend"] == "aot_eager" and out["torch_compile_step_ms"] >= 0
    assert speed._first_call_s(lambda: None, 1) >= 0


def test_a_compile_past_the_limit_is_a_timeout_whatever_the_backend_raises():
    import time

    def slow():
        try:
            time.sleep(3)
        except TimeoutError as e:
            raise RuntimeError("compile-worker future did not complete") from e

    with pytest.raises(TimeoutError, match="within 1 s"):
        speed._first_call_s(slow, 1)


def test_table_cells_ratios_and_missing_torch():
    row = {"preset": "improved", "batch": 16, "rows": 66, "frames": 168, "channels": [8, 16], "params": 5e5,
           "compile_train": (20.0, 2.0), "jax_step_ms": 100.0, "torch_step_ms": 250.0,
           "torch_compile_step_ms": 150.0, "torch_compile_backend": "inductor", "torch_compile_s": 140.0}
    sc = {"gen_params": 27.1e6, "batch": 32, "n_trans": 50, "jax_step_ms": 2000.0, "torch_step_ms": 4000.0,
          "compile_train": (17.0, 4.0)}
    md = speed.markdown(_record(row, sc))
    assert "| 100 ms | 250 ms | 150 ms (inductor, 140 s) | 2.50x | 1.50x |" in md
    assert "| 2000 ms | 4000 ms | did not compile | 2.00x | - |" in md
    bare = {k: v for k, v in row.items() if not k.startswith("torch")}
    md = speed.markdown(_record(bare, {k: v for k, v in sc.items() if not k.startswith("torch")}))
    assert md.count("| 100 ms | torch not installed | torch not installed | - | - |") == 1
    assert "CAE train step, `improved` | 20.0 / 2.0 |" in md
