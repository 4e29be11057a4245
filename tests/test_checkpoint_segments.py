"""Checkpoints write only the replay's new episodes (shared segments), and still fall back."""

import json
from pathlib import Path

import numpy as np
import pytest
from test_agent_replay import filled_replay

from curious.agent.replay import EpisodeReplay
from curious.runs import checkpoint
from curious.runs.checkpoint import CheckpointError
from curious.runs.folder_layout import list_checkpoints


def grown(n: int, evicted: bool = False) -> dict:
    """A replay `state_dict` of `n` episodes whose values say which episode they hold."""
    episodes = np.arange(n)
    return {
        "states": np.repeat(episodes[:, None], 3, axis=1).astype(np.float32),
        "modules": episodes.astype(np.int64),
        "size": np.int64(n),
        "ptr": np.int64(n),
        "evicted": np.bool_(evicted),
    }


def save_run(directory: Path, sizes: list[int]) -> list[Path]:
    """Checkpoints of one run whose replay holds `sizes[i]` episodes at its i-th checkpoint."""
    paths, base = [], None
    for i, n in enumerate(sizes):
        base = checkpoint.save(directory, 10 * (i + 1), {"step": i}, grown(n), base=base)
        paths.append(base)
    return paths


def manifest(path: Path) -> dict:
    return json.loads((path / checkpoint.MANIFEST).read_text())


def segment_files(directory: Path) -> list[str]:
    return sorted(p.name for p in (directory / checkpoint.SEGMENTS).iterdir())


def test_each_checkpoint_writes_only_the_episodes_after_the_one_before(tmp_path):
    paths = save_run(tmp_path, [5, 12, 12, 20])
    kept = list_checkpoints(tmp_path)
    assert kept == paths[-2:]  # the two newest, as before
    assert not (kept[-1] / "replay.npz").exists()
    rows = manifest(kept[-1])["segments"]
    assert [(first, end) for _, first, end in rows] == [(0, 5), (5, 12), (12, 20)]
    assert manifest(kept[-2])["segments"] == rows[:2]  # the one before shares its segments
    # each episode is on disk once: the segments' sizes add up to one replay
    assert segment_files(tmp_path) == [name for name, *_ in rows]
    for path, n in zip(kept, [12, 20], strict=True):
        _, replay = checkpoint.load(path)
        expected = grown(n)
        assert set(replay) == set(expected)
        for key, value in expected.items():
            np.testing.assert_array_equal(replay[key], value, err_msg=key)


def test_a_damaged_newest_segment_falls_back_to_the_checkpoint_before(tmp_path):
    paths = save_run(tmp_path, [4, 9])
    newest = manifest(paths[-1])["segments"][-1][0]
    (tmp_path / checkpoint.SEGMENTS / newest).write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(CheckpointError, match="cannot read checkpoint"):
        checkpoint.load(paths[-1], replay=False)  # an evaluation refuses it too
    with pytest.warns(UserWarning, match="resuming from the one before"):
        path, _, replay = checkpoint.load_latest(tmp_path)
    assert path == paths[0] and int(replay["size"]) == 4
    # the run goes on from there: its next checkpoint rewrites the damaged episodes
    again = checkpoint.save(tmp_path, 20, {"step": 1}, grown(9), base=path)
    assert again == paths[-1]
    np.testing.assert_array_equal(checkpoint.load(again)[1]["modules"], np.arange(9))


def test_segments_no_kept_checkpoint_lists_are_removed(tmp_path):
    save_run(tmp_path, [3, 6])
    orphan = tmp_path / checkpoint.SEGMENTS / "episodes-000000000006-000000000009.npz"
    orphan.write_bytes(b"a segment whose checkpoint was never renamed into place")
    (tmp_path / checkpoint.SEGMENTS / ".tmp-episodes-x.npz").write_bytes(b"half")
    checkpoint.remove_partial(tmp_path)
    checkpoint.prune(tmp_path)
    assert segment_files(tmp_path) == [
        "episodes-000000000000-000000000003.npz",
        "episodes-000000000003-000000000006.npz",
    ]


def test_an_unreadable_manifest_keeps_every_segment(tmp_path):
    """While a kept checkpoint's manifest cannot be read, it might list any segment: even one
    that no readable manifest lists stays; once the manifest reads again, that one goes."""
    paths = save_run(tmp_path, [3, 6])
    unlisted = tmp_path / checkpoint.SEGMENTS / "episodes-000000000006-000000000009.npz"
    unlisted.write_bytes(b"a segment no readable manifest lists")
    good = (paths[0] / checkpoint.MANIFEST).read_text()
    (paths[0] / checkpoint.MANIFEST).write_text("{")
    before = segment_files(tmp_path)
    checkpoint.prune(tmp_path)
    assert segment_files(tmp_path) == before and unlisted.name in before
    (paths[0] / checkpoint.MANIFEST).write_text(good)
    checkpoint.prune(tmp_path)
    assert unlisted.name not in segment_files(tmp_path)
    assert len(segment_files(tmp_path)) == 2


def test_without_a_checkpoint_to_build_on_the_whole_replay_is_one_segment(tmp_path):
    checkpoint.save(tmp_path, 10, {}, grown(4))
    path = checkpoint.save(tmp_path, 20, {}, grown(7))  # no base: a resume lost its trail
    assert [row[1:] for row in manifest(path)["segments"]] == [[0, 7]]


def test_a_replay_that_evicted_is_written_whole(tmp_path):
    base = checkpoint.save(tmp_path, 10, {}, grown(4))
    path = checkpoint.save(tmp_path, 20, {}, grown(4, evicted=True), base=base)
    assert (path / "replay.npz").exists() and not (path / checkpoint.MANIFEST).exists()
    np.testing.assert_array_equal(checkpoint.load(path)[1]["modules"], np.arange(4))


def test_the_replay_says_when_it_first_stores_over_an_episode():
    replay, _ = filled_replay(n=60)  # capacity 200
    assert not replay.state_dict()["evicted"]
    more, _ = filled_replay(n=150, seed=1)
    arrays = more.state_dict()
    keys = ("states", "achieved", "actions", "modules", "goals")
    replay.store(*(arrays[k][:140] for k in keys))
    assert not replay.state_dict()["evicted"]  # 200 slots, 200 episodes stored: none over another
    replay.store(*(arrays[k][140:141] for k in keys))
    assert replay.state_dict()["evicted"]
    # a dict written before the flag existed: evicted unless its ring never wrapped
    old = {k: v for k, v in more.state_dict().items() if k != "evicted"}
    fresh = EpisodeReplay(more.spec, capacity=200)
    fresh.load_state_dict(old)
    assert not fresh.evicted
    old["ptr"] = np.int64(0)
    fresh.load_state_dict(old)
    assert fresh.evicted


def test_a_checkpoint_written_whole_resumes_and_the_next_starts_the_segments(tmp_path):
    """A run checkpointed before segments existed (`replay.npz`, no eviction flag) goes on."""
    old = {k: v for k, v in grown(6).items() if k != "evicted"}
    base = checkpoint.save(tmp_path, 10, {}, old)
    assert (base / "replay.npz").exists()
    path, _, replay = checkpoint.load_latest(tmp_path)
    assert int(replay["size"]) == 6 and "evicted" not in replay  # as such a checkpoint held it
    path = checkpoint.save(tmp_path, 20, {}, grown(8), base=path)
    assert [row[1:] for row in manifest(path)["segments"]] == [[0, 8]]
    np.testing.assert_array_equal(checkpoint.load(path)[1]["modules"], np.arange(8))


def test_a_replay_is_read_into_the_arrays_that_will_hold_it(tmp_path):
    """A resume reads the segments into its replay's own arrays (`into`) rather than into new
    ones, so that it holds the replay once while it loads; arrays that cannot hold them (too
    few episodes, another type) are left as they are and new ones come back."""
    paths = save_run(tmp_path, [5, 12])
    room = {
        "states": np.full((20, 3), -1, np.float32),
        "modules": np.full(20, -1, np.int64),
    }
    _, replay = checkpoint.load(paths[-1], into=room)
    for key in ("states", "modules"):
        assert np.shares_memory(replay[key], room[key]), key
        np.testing.assert_array_equal(room[key][:12], grown(12)[key], err_msg=key)
        assert (room[key][12:] == -1).all(), key  # the slots after the replay untouched
    small = {"states": np.zeros((10, 3), np.float32), "modules": np.zeros(20, np.int32)}
    _, replay = checkpoint.load(paths[-1], into=small)
    for key in ("states", "modules"):
        assert not np.shares_memory(replay[key], small[key]), key
        assert not small[key].any(), key
        np.testing.assert_array_equal(replay[key], grown(12)[key], err_msg=key)
