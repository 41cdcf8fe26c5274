import subprocess
import sys

import pytest

from dgt_lib.cli import build_parser, main
from dgt_lib.stages import registry as pipeline


def test_reproduce_runs_and_summarises(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("DGT_DATA_DIR", str(tmp_path))
    monkeypatch.setattr(pipeline, "STAGES", [])
    assert main(["reproduce", "--profile", "smoke"]) == 0
    out = capsys.readouterr().out
    assert "profile 'smoke'" in out and str(tmp_path / "smoke") in out
    assert "no stages yet" in out


def test_reproduce_runs_registered_stages_in_order_with_summary(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("DGT_DATA_DIR", str(tmp_path))
    stages = [
        pipeline.Stage("first", "tests.stage_examples:first", "writes a file"),
        pipeline.Stage("second", "tests.stage_examples:second", "reads it"),
    ]
    monkeypatch.setattr(pipeline, "STAGES", stages)
    assert main(["reproduce", "--profile", "smoke", "--stages", "second", "first"]) == 0
    out = capsys.readouterr().out
    assert out.index("first") < out.index("second")  # pipeline order, not argument order
    assert "wrote 1 file" in out and str(tmp_path / "smoke" / "seed-0" / "example.json") in out


def test_reproduce_runs_every_stage_for_every_seed_each_in_its_own_directory(
        capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("DGT_DATA_DIR", str(tmp_path))
    monkeypatch.setattr(pipeline, "STAGES", [
        pipeline.Stage("first", "tests.stage_examples:first", "writes a file"),
        pipeline.Stage("second", "tests.stage_examples:second", "reads it")])
    assert main(["reproduce", "--profile", "smoke", "--seeds", "3"]) == 0
    out = capsys.readouterr().out
    assert "seed(s) 0, 1, 2" in out
    for seed in (0, 1, 2):
        assert (tmp_path / "smoke" / f"seed-{seed}" / "example.json").exists()
        assert f"read n=1 of seed {seed}" in out
    assert main(["reproduce", "--profile", "smoke", "--seeds", "0"]) == 2
    assert "--seeds must be ≥ 1" in capsys.readouterr().err


def test_unknown_stage_and_profile_are_clear_errors(capsys, monkeypatch):
    monkeypatch.setattr(pipeline, "STAGES", [pipeline.Stage("a", "x:y", "d")])
    assert main(["reproduce", "--stages", "nope"]) == 2
    assert "unknown stage(s) nope; valid stages: a" in capsys.readouterr().err
    monkeypatch.setenv("DGT_PROFILE", "huge")
    assert main(["reproduce"]) == 2
    assert "valid profiles: smoke, demo, paper" in capsys.readouterr().err


def test_python_dash_m_entry_point():
    done = subprocess.run([sys.executable, "-m", "dgt_lib", "--help"], capture_output=True,
                          text=True, check=True)
    assert "reproduce" in done.stdout


def test_profile_names_follow_one_rule_on_the_command_line_and_in_the_environment(
        capsys, tmp_path, monkeypatch):
    """`DGT_PROFILE=Smoke` works, so `--profile Smoke` must too (case-insensitive both)."""
    monkeypatch.setenv("DGT_DATA_DIR", str(tmp_path))
    monkeypatch.setattr(pipeline, "STAGES", [])
    monkeypatch.setenv("DGT_PROFILE", "Smoke")
    assert main(["reproduce"]) == 0
    assert "profile 'smoke'" in capsys.readouterr().out
    monkeypatch.delenv("DGT_PROFILE")
    assert main(["reproduce", "--profile", "Smoke"]) == 0
    assert "profile 'smoke'" in capsys.readouterr().out
    args = build_parser().parse_args(["plan", "--world", "hill", "--vehicle", "jeep",
                                      "--start", "1,2,0", "--goal", "3,4", "--profile", "PAPER"])
    assert args.profile == "paper"
    with pytest.raises(SystemExit):
        main(["reproduce", "--profile", "huge"])
    assert "valid profiles: smoke, demo, paper" in capsys.readouterr().err
