"""``inbetween speed``, ``sweep``, ``select-checkpoint``, ``calibrate-gate``, ``build-bank`` and ``ship-weights``:
the tools a pip user (no experiments/ folder) runs.  Each is listed by ``inbetween --help``, has its own
``--help`` and reports an argument error in one line with status 2 before JAX is imported; the PyTorch references
of the speed section are package modules; the docs name only experiments/ scripts that exist.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from inbetween_jax.cli import main
from inbetween_jax.errors import UserError

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TOOLS = ("speed", "sweep", "select-checkpoint", "calibrate-gate", "build-bank", "ship-weights")


def test_top_level_help_lists_the_tools(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for tool in TOOLS:
        assert f"\n    {tool}" in out and f"inbetween {tool} " in out, tool


@pytest.mark.parametrize("tool", TOOLS)
def test_each_tool_has_help(tool, capsys):
    assert main([tool, "--help"]) == 0
    out, err = capsys.readouterr()
    assert out.startswith(f"usage: inbetween {tool}") and not err
    assert "``" not in out and ":mod:" not in out


ERRORS = [
    (["speed", "--reps", "0"], "--reps must be >= 1"),
    (["speed", "--torch-ref", "missing.py"], "--torch-ref missing.py: no such file"),
    (["sweep", "--rows", "full,no_such_row"], "unknown row 'no_such_row'"),
    (["sweep", "--seeds", "2", "model.no_such_key=1"], "model.no_such_key"),
    (["ship-weights", "no_such_run"], "no_such_run: no such run folder"),
    (["ship-weights", "."], "not a run folder"),
    (["ship-weights"], "required: RUN_DIR"),
    (["select-checkpoint", "no_such_run"], "no_such_run: no such run folder"),
    (["calibrate-gate", "."], "not a run folder"),
    (["build-bank", ".", "--set", "model.bank_k"], "--set model.bank_k: expected KEY=VALUE"),
    (["build-bank", "."], "not a run folder"),
]


@pytest.mark.parametrize("argv,says", ERRORS, ids=lambda a: a if isinstance(a, str) else "_".join(a))
def test_argument_errors_are_one_line_before_jax(argv, says, tmp_path):
    code = ("import sys; from inbetween_jax.cli import main; rc = main(sys.argv[1:]); "
            "print('jax' in sys.modules, rc)")
    res = subprocess.run([sys.executable, "-c", code] + argv, capture_output=True, text=True, timeout=120,
                         cwd=tmp_path)
    assert res.stdout.split() == ["False", "2"], res.stdout + res.stderr
    assert res.stderr.count("\n") == 1 and res.stderr.startswith("inbetween: error: ") and says in res.stderr, \
        res.stderr
    assert not os.listdir(tmp_path)                                   # nothing written


def test_calibrate_kind_is_refused_where_the_gate_has_one_score(cli_runs, tmp_path):
    """``calibrate-gate --kind`` on the interaction model (one score): a one-line error before JAX, nothing written."""
    before = sorted(os.listdir(cli_runs["interaction"]))
    code = ("import sys; from inbetween_jax.cli import main; rc = main(sys.argv[1:]); "
            "print('jax' in sys.modules, rc)")
    res = subprocess.run([sys.executable, "-c", code, "calibrate-gate", cli_runs["interaction"], "--kind", "travel"],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert res.stdout.split() == ["False", "2"], res.stdout + res.stderr
    assert res.stderr.count("\n") == 1 and "gate has one score (no --kind)" in res.stderr, res.stderr
    assert sorted(os.listdir(cli_runs["interaction"])) == before and not os.listdir(tmp_path)


def test_docs_name_only_experiments_scripts_that_exist():
    """The README, the results pages and the package name experiments/ scripts that exist (the pipeline's tools
    are subcommands now)."""
    import glob
    import re
    paths = [os.path.join(ROOT, "README.md")] + glob.glob(os.path.join(ROOT, "docs", "results", "*.md")) + \
        glob.glob(os.path.join(ROOT, "inbetween_jax", "**", "*.py"), recursive=True)
    named = set()
    for path in paths:
        named |= set(re.findall(r"experiments/(\w+\.py)", open(path).read()))
    assert named, "no experiments/ script named anywhere: the pattern is wrong"
    missing = sorted(n for n in named if not os.path.isfile(os.path.join(ROOT, "experiments", n)))
    assert not missing, missing


def test_speed_appends_to_the_bench_files_only_when_both_exist(tmp_path):
    from inbetween_jax.cli.speed_cmd import append_to_bench
    out = {"markdown": "## Speed\n| row |", "wall_s": 1.5, "scvae": {"infer_10_ms": 3.0}}
    assert not append_to_bench(out, str(tmp_path))
    (tmp_path / "bench.md").write_text("# Bench\n")
    assert not append_to_bench(out, str(tmp_path))
    (tmp_path / "bench.json").write_text(json.dumps({"rows": [1]}))
    assert append_to_bench(out, str(tmp_path))
    assert (tmp_path / "bench.md").read_text() == "# Bench\n\n## Speed\n| row |\n"
    assert json.loads((tmp_path / "bench.json").read_text()) == {"rows": [1], "speed": {
        "wall_s": 1.5, "scvae": {"infer_10_ms": 3.0}}}


def test_speed_torch_reference_is_checked(tmp_path):
    import importlib.util
    from inbetween_jax.cli.speed_cmd import load_torch_ref, skip_reason
    has_torch = importlib.util.find_spec("torch") is not None
    default = load_torch_ref(None)                                    # the package's reference, when torch is there
    assert (default is not None) == has_torch
    if has_torch:
        assert default.__name__ == "inbetween_jax.evaluation.torch_ref.scvae" and default.available()
    wrong = tmp_path / "not_a_reference.py"
    wrong.write_text("def available():\n    return False\n")
    with pytest.raises(UserError, match="defines no make_step"):
        load_torch_ref(str(wrong))
    ref = load_torch_ref(os.path.join(ROOT, "inbetween_jax", "evaluation", "torch_ref", "scvae.py"))
    assert callable(ref.make_step)
    assert ("torch not installed" in skip_reason()) == (not ref.available())


def test_readme_and_makefile_use_the_subcommands():
    """What a pip user reads runs without experiments/; ``make bench`` (not ``make test``) installs the bench extra
    before the speed section."""
    readme = open(os.path.join(ROOT, "README.md")).read()
    for script in ("bench_speed.py", "ship_weights.py", "sweep.py", "select_checkpoint.py", "calibrate_gate.py",
                   "build_bank.py", "torch_scvae.py"):
        assert f"python experiments/{script}" not in readme, script
    assert "inbetween sweep --seeds 3" in readme and "inbetween ship-weights RUN_DIR" in readme
    rules = {}
    for line in open(os.path.join(ROOT, "Makefile")).read().splitlines():
        if line and not line[0].isspace() and ":" in line and "=" not in line.split(":", 1)[0]:
            name, prereqs = line.split(":", 1)
            rules[name.strip()] = prereqs.split()
    assert "install-bench" in " ".join(rules["bench"]) and "install-bench" not in rules["test"]
    assert "install" in rules["test"]
    make = open(os.path.join(ROOT, "Makefile")).read()
    assert 'pip install --quiet -e ".[bench]"' in make and "inbetween speed --results" in make and "--torch-ref" not in make


def test_speed_command_wiring(tmp_path, monkeypatch, capsys):
    """``inbetween speed`` hands the reference module and the skip reason to the speed section and appends its
    markdown to an existing bench.md / bench.json (the section itself is stubbed: it takes minutes)."""
    from inbetween_jax.evaluation import speed
    seen = {}

    def fake_run(source, results_dir, reps, quick, torch_ref=None, torch_skip=None, **kw):
        seen.update(source=source, reps=reps, quick=quick, torch_ref=torch_ref, torch_skip=torch_skip)
        return {"markdown": "## Speed (stub)", "wall_s": 0.0}

    monkeypatch.setattr(speed, "run", fake_run)
    (tmp_path / "bench.md").write_text("# Bench\n")
    (tmp_path / "bench.json").write_text("{}")
    ref = os.path.join(ROOT, "inbetween_jax", "evaluation", "torch_ref", "scvae.py")
    assert main(["speed", "--results", str(tmp_path), "--reps", "2", "--quick", "--torch-ref", ref]) == 0
    assert seen["reps"] == 2 and seen["quick"] and callable(seen["torch_ref"].make_step) and seen["torch_skip"] is None
    assert "## Speed (stub)" in capsys.readouterr().out
    assert (tmp_path / "bench.md").read_text().endswith("## Speed (stub)\n")
    assert json.loads((tmp_path / "bench.json").read_text()) == {"speed": {"wall_s": 0.0}}
    assert main(["speed", "--results", str(tmp_path / "other")]) == 0    # no --torch-ref: the package's, if torch
    import importlib.util
    if importlib.util.find_spec("torch") is None:
        assert seen["torch_ref"] is None and "torch not installed" in seen["torch_skip"]
    else:
        assert seen["torch_ref"].__name__.endswith("torch_ref.scvae") and seen["torch_skip"] is None
