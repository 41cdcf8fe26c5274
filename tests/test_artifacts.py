import copy
import errno
import json
import os
import stat

import numpy as np
import pytest

from dgt_lib.core import artifacts
from dgt_lib.core.cache_keys import jsonable as key_form
from dgt_lib.core.config import get_profile


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    return tmp_path


class Builder:
    """Counts builds, returns a known array."""

    def __init__(self, value=1.0):
        self.calls = 0
        self.value = value

    def __call__(self):
        self.calls += 1
        return {"x": np.full((4, 3), self.value, dtype=np.float32)}


def test_artifacts_live_under_data_profile(data_dir):
    build = Builder()
    artifacts.ensure("stage/out.npz", {"a": 1}, build, profile="smoke")
    assert (data_dir / "smoke" / "stage" / "out.npz").exists()
    meta = json.loads((data_dir / "smoke" / "stage" / "out.npz.meta.json").read_text())
    assert meta["config_hash"] == artifacts.config_hash({"a": 1})


def test_second_call_loads_instead_of_building():
    build = Builder()
    a = artifacts.ensure("out.npz", {"a": 1}, build, profile="smoke")
    b = artifacts.ensure("out.npz", {"a": 1}, build, profile="smoke")
    assert build.calls == 1
    np.testing.assert_array_equal(a["x"], b["x"])


def test_changed_config_rebuilds_with_a_one_line_message():
    messages = []
    artifacts.ensure("out.npz", {"a": 1}, Builder(1.0), profile="smoke", log=messages.append)
    rebuilt = Builder(2.0)
    out = artifacts.ensure("out.npz", {"a": 2}, rebuilt, profile="smoke", log=messages.append)
    assert rebuilt.calls == 1 and out["x"][0, 0] == 2.0
    assert len(messages) == 1 and "configuration changed" in messages[0]
    assert "\n" not in messages[0]


def test_a_rebuild_names_the_settings_that_changed():
    cfg = {"physics": {"timestep_s": 0.004, "cone": "pyramidal"}, "episode": {"speed": 5.0},
           "seed": 0}
    artifacts.ensure("e.npz", cfg, Builder(1.0), profile="smoke", log=lambda _: None)
    new = {**cfg, "physics": {"timestep_s": 0.008, "cone": "pyramidal"}}
    assert artifacts.staleness("e.npz", new, profile="smoke") == (
        "configuration changed (physics.timestep_s)")
    assert artifacts.staleness("e.npz", {**new, "seed": 1, "extra": 2}, profile="smoke") == (
        "configuration changed (extra, physics.timestep_s, seed)")
    assert artifacts.staleness("e.npz", cfg, profile="smoke") is None
    assert artifacts.staleness("other.npz", cfg, profile="smoke") == "missing"
    with_array = {"bev": np.zeros(3), "seed": 0}
    artifacts.ensure("a.npz", with_array, Builder(1.0), profile="smoke", log=lambda _: None)
    assert artifacts.staleness("a.npz", {"bev": np.ones(3), "seed": 0}, profile="smoke") == (
        "configuration changed (bev)")


def test_many_stale_artifacts_are_reported_in_one_line():
    lines: list[str] = []
    changed = "configuration changed (physics)"
    artifacts.report_rebuilds([changed] * 130 + [None, "missing"], "episodes (demo)",
                              log=lines.append)
    assert lines == ["[dgt] 130 episodes (demo) to rebuild: configuration changed (physics)"]
    artifacts.report_rebuilds(["missing", None], "episodes (demo)", log=lines.append)
    assert len(lines) == 1  # a first run says nothing
    artifacts.report_rebuilds([changed, changed, "corrupt (x)"], "episodes", log=lines.append)
    assert lines[-1] == ("[dgt] 3 episodes to rebuild: 2 configuration changed (physics); "
                         "1 corrupt (x)")


@pytest.mark.parametrize("damage", ["truncate", "garbage", "flip_byte"])
def test_corrupt_file_is_reported_and_rebuilt_never_used(data_dir, damage):
    artifacts.ensure("out.npz", {"a": 1}, Builder(1.0), profile="smoke")
    path = data_dir / "smoke" / "out.npz"
    raw = path.read_bytes()
    if damage == "truncate":
        path.write_bytes(raw[: len(raw) // 2])
    elif damage == "garbage":
        path.write_bytes(b"not a zip file at all")
    else:
        path.write_bytes(raw[:-10] + bytes([raw[-10] ^ 0xFF]) + raw[-9:])
    messages = []
    rebuilt = Builder(3.0)
    out = artifacts.ensure("out.npz", {"a": 1}, rebuilt, profile="smoke", log=messages.append)
    assert rebuilt.calls == 1 and out["x"][0, 0] == 3.0
    assert "corrupt" in messages[0]
    # and the rebuilt artifact is valid again
    again = Builder()
    artifacts.ensure("out.npz", {"a": 1}, again, profile="smoke")
    assert again.calls == 0


def test_unreadable_file_with_matching_checksum_is_rebuilt(data_dir):
    """A file whose metadata matches but which cannot be parsed (e.g. written by a bug)."""
    path = data_dir / "smoke" / "out.pkl"
    artifacts.ensure("out.pkl", {"a": 1}, lambda: {"ok": True}, profile="smoke")
    path.write_bytes(b"\x80\x05garbage")
    meta_path = path.with_name("out.pkl.meta.json")
    meta = json.loads(meta_path.read_text())
    meta["size"] = path.stat().st_size
    meta["sha256"] = artifacts._file_digest(path)
    meta_path.write_text(json.dumps(meta))
    messages = []
    out = artifacts.ensure("out.pkl", {"a": 1}, lambda: {"ok": 2}, profile="smoke",
                           log=messages.append)
    assert out == {"ok": 2} and "corrupt" in messages[0]


def test_missing_metadata_rebuilds(data_dir):
    artifacts.ensure("out.json", {"a": 1}, lambda: {"v": 1}, profile="smoke")
    (data_dir / "smoke" / "out.json.meta.json").unlink()
    messages = []
    out = artifacts.ensure("out.json", {"a": 1}, lambda: {"v": 2}, profile="smoke",
                           log=messages.append)
    assert out == {"v": 2} and "no metadata" in messages[0]


def test_crash_during_build_or_write_leaves_no_artifact(data_dir):
    def failing():
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        artifacts.ensure("out.npz", {"a": 1}, failing, profile="smoke")
    assert not (data_dir / "smoke" / "out.npz").exists()

    with pytest.raises(TypeError):  # np.savez cannot store an object that is not a mapping
        artifacts.ensure("bad.npz", {"a": 1}, lambda: 42, profile="smoke")
    leftovers = [p.name for p in (data_dir / "smoke").iterdir() if p.suffix != ".lock"]
    assert leftovers == [], leftovers  # no half-written file, no temporary file (the
    # build locks stay: artifacts.build_lock)


def test_config_hash_is_stable_and_sensitive():
    p = get_profile("smoke")
    assert artifacts.config_hash(p) == artifacts.config_hash(get_profile("smoke"))
    assert artifacts.config_hash(p) != artifacts.config_hash(p.with_(seed=1))
    assert artifacts.config_hash({"b": 1, "a": 2}) == artifacts.config_hash({"a": 2, "b": 1})
    assert artifacts.config_hash(np.zeros(3)) != artifacts.config_hash(np.ones(3))
    with pytest.raises(TypeError):
        artifacts.config_hash(object())


def test_a_settings_object_used_many_times_hashes_as_its_copies_do():
    """A key that repeats one settings object (the 1,300 episodes of `paper` share the
    profile's worlds and vehicles) converts it once; the key is what distinct equal copies
    give, so caches written before are still valid."""
    p = get_profile("paper")
    shared = [{"worlds": p.worlds, "collect": p.collect, "i": i} for i in range(3)]
    copies = [{"worlds": copy.deepcopy(p.worlds), "collect": copy.deepcopy(p.collect), "i": i}
              for i in range(3)]
    assert artifacts.config_hash(shared) == artifacts.config_hash(copies)
    assert key_form(shared) == key_form(copies)
    copies[2]["worlds"] = get_profile("demo").worlds
    assert artifacts.config_hash(shared) != artifacts.config_hash(copies)


@pytest.mark.parametrize("suffix,value", [
    (".npz", {"a": np.arange(5)}),
    (".json", {"a": [1, 2]}),
    (".pkl", {"a": (1, "x")}),
    (".pt", {"w": np.ones(2)}),
])
def test_formats_round_trip(tmp_path, suffix, value):
    path = tmp_path / f"f{suffix}"
    artifacts.save(path, value)
    back = artifacts.load(path)
    assert set(back) == set(value)
    for k in value:
        np.testing.assert_array_equal(np.asarray(back[k]), np.asarray(value[k]))


def test_a_fingerprint_keys_what_is_built_on_an_artifact_by_content():
    """Dependents are keyed by stored_digest: the fingerprint when one was given (what the
    value means), else the file's SHA-256 (which changes with incidental bytes)."""
    def build(seconds):
        return lambda: {"weights": [1, 2], "seconds": seconds}

    def meaning(value):
        return str(value["weights"])

    artifacts.ensure("m.json", {"v": 1}, build(3.2), profile="smoke", fingerprint=meaning)
    first = artifacts.stored_digest("m.json", profile="smoke")
    artifacts.ensure("m.json", {"v": 2}, build(4.7), profile="smoke", fingerprint=meaning,
                     log=lambda _: None)
    assert artifacts.stored_digest("m.json", profile="smoke") == first == "[1, 2]"
    artifacts.ensure("p.json", {"v": 1}, build(3.2), profile="smoke")
    plain = artifacts.stored_digest("p.json", profile="smoke")
    artifacts.ensure("p.json", {"v": 2}, build(4.7), profile="smoke", log=lambda _: None)
    assert artifacts.stored_digest("p.json", profile="smoke") != plain


@pytest.mark.parametrize("umask, mode", [(0o022, 0o644), (0o002, 0o664), (0o077, 0o600)])
@pytest.mark.parametrize("suffix", [".npz", ".json", ".pkl", ".pt"])
def test_a_written_artifact_has_the_mode_the_umask_allows(data_dir, umask, mode, suffix):
    """Atomic writes go through a private temporary file; the artifact and its metadata
    end with the mode a plain ``open()`` would give them, so a group sharing a data
    directory on a cluster (umask 002) can read each other's artifacts."""
    value = {"a": np.arange(3)} if suffix in (".npz", ".pt") else {"a": 1}
    old = os.umask(umask)
    try:
        artifacts.ensure(f"x{suffix}", {"k": 1}, lambda: value, profile="smoke")
    finally:
        os.umask(old)
    path = data_dir / "smoke" / f"x{suffix}"
    for written in (path, path.with_name(path.name + ".meta.json")):
        assert stat.S_IMODE(written.stat().st_mode) == mode, written.name


ENSURE_SLOWLY = """
import os, sys, time
import numpy as np
from dgt_lib.core import artifacts

def build():
    with open(sys.argv[1], "a") as f:
        f.write(f"{os.getpid()}\\n")
    time.sleep(float(sys.argv[2]))
    return {"x": np.arange(1000)}

value = artifacts.ensure("slow.npz", {"a": 1}, build, profile="smoke")
print("sum", int(value["x"].sum()))
"""


def test_a_second_process_waits_for_the_build_and_loads_it(data_dir, tmp_path):
    """Two processes ensure one artifact at once: the second waits on the build lock and
    loads what the first built, instead of building it again or calling it corrupt
    (its metadata is written after the file)."""
    import subprocess
    import sys
    import time

    builds = tmp_path / "builds.txt"
    env = {**os.environ, artifacts.DATA_ENV_VAR: str(data_dir)}

    def start(seconds):
        return subprocess.Popen([sys.executable, "-c", ENSURE_SLOWLY, str(builds),
                                 str(seconds)], env=env, text=True,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT)

    first = start(2.0)
    deadline = time.monotonic() + 60
    while not builds.exists() and time.monotonic() < deadline:
        time.sleep(0.02)
    second = start(0.0)
    said = [p.communicate(timeout=60)[0] for p in (first, second)]
    assert [first.returncode, second.returncode] == [0, 0], said
    assert builds.read_text().split() == [str(first.pid)]
    assert said == ["sum 499500\n"] * 2  # and no "rebuilding … corrupt" line


@pytest.mark.parametrize("code", [errno.EROFS, errno.EACCES])
def test_an_artifact_to_build_in_a_directory_it_cannot_write_fails_before_its_build(
        data_dir, monkeypatch, code):
    """The directory is tried before the build starts (minutes of simulation would be
    lost otherwise); the error names the artifact, not a temporary file."""
    def refuse(*args, **kwargs):
        raise OSError(code, os.strerror(code), "/somewhere/.tmp")

    build = Builder()
    monkeypatch.setattr(artifacts.tempfile, "mkstemp", refuse)
    with pytest.raises(OSError) as caught:
        artifacts.ensure("stage/out.npz", {"a": 1}, build, profile="smoke")
    assert caught.value.errno == code and build.calls == 0
    assert caught.value.filename == str(data_dir / "smoke" / "stage" / "out.npz")
