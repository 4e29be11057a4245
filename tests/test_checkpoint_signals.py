"""A Ctrl-C while a checkpoint is written is taken once the checkpoint is written whole."""

import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import torch

from curious.runs import checkpoint
from curious.runs.folder_layout import list_checkpoints


class Stopped(Exception):
    """What the test's SIGINT handler raises (a `KeyboardInterrupt` would stop pytest)."""


@pytest.fixture
def sigint_stops():
    def stop(signum, frame):
        raise Stopped

    previous = signal.signal(signal.SIGINT, stop)
    yield
    signal.signal(signal.SIGINT, previous)


def replay(n: int) -> dict:
    return {"states": np.arange(3 * n, dtype=np.float32).reshape(n, 3), "size": np.int64(n)}


@pytest.mark.parametrize("grows_only", [True, False], ids=["segments", "whole"])
def test_a_ctrl_c_in_the_middle_of_a_checkpoint_stops_after_it(
    tmp_path, monkeypatch, sigint_stops, grows_only
):
    """The signal comes as the networks' file is begun: without the hold it would stop the
    write there (no checkpoint, a temporary folder left, or torch's "unexpected pos" error in
    place of the Ctrl-C, or the process aborted)."""
    saved = torch.save

    def interrupted_save(obj, handle):
        os.kill(os.getpid(), signal.SIGINT)
        saved(obj, handle)

    first = checkpoint.save(tmp_path, 10, {"step": 1}, {**replay(4), "evicted": np.bool_(False)})
    monkeypatch.setattr(torch, "save", interrupted_save)
    extra = {"evicted": np.bool_(False)} if grows_only else {}
    with pytest.raises(Stopped):
        checkpoint.save(tmp_path, 20, {"step": 2}, {**replay(7), **extra}, base=first)
    monkeypatch.undo()
    newest = list_checkpoints(tmp_path)[-1]
    assert newest.name == checkpoint.checkpoint_name(20)
    assert not list(tmp_path.rglob(".tmp-*"))  # nor a temporary segment
    state, stored = checkpoint.load(newest)
    assert state["step"] == 2
    np.testing.assert_array_equal(stored["states"], replay(7)["states"])
    assert signal.getsignal(signal.SIGINT).__name__ == "stop"  # the handler is put back


SIGNALS_AT_RANDOM = textwrap.dedent(
    """
    import os, random, signal, sys, threading, time
    from pathlib import Path
    import numpy as np, torch
    from curious.runs import checkpoint
    from curious.runs.folder_layout import list_checkpoints

    random.seed(0)
    torch.manual_seed(0)
    net = torch.nn.Sequential(torch.nn.Linear(64, 256), torch.nn.Linear(256, 256))
    optimiser = torch.optim.Adam(net.parameters())
    net(torch.ones(1, 64)).sum().backward()
    optimiser.step()
    state = {"net": net.state_dict(), "optimiser": optimiser.state_dict()}
    directory = Path(sys.argv[1])

    def grown(n):
        return {"states": np.ones((n, 50), np.float32), "size": np.int64(n),
                "evicted": np.bool_(False)}

    tic = time.perf_counter()
    base = checkpoint.save(directory, 1, state, grown(100))
    took = time.perf_counter() - tic
    fired, inside, missing = [], 0, []
    write = checkpoint._save

    def write_signalled(*args):  # the signal's clock starts as the write does
        timer.start()
        return write(*args)

    checkpoint._save = write_signalled
    for i in range(2, 32):
        timer = threading.Timer(
            random.uniform(0.0, took),
            lambda: (fired.append(time.perf_counter()), os.kill(os.getpid(), signal.SIGINT)),
        )
        try:
            start = time.perf_counter()
            try:
                checkpoint.save(directory, i, state, grown(100 * i), base=base)
            finally:
                end = time.perf_counter()
            timer.join()
            time.sleep(0.05)
        except KeyboardInterrupt:
            pass
        timer.join()
        inside += bool(fired and start <= fired[-1] <= end)
        kept = list_checkpoints(directory)
        if not kept or kept[-1].name != checkpoint.checkpoint_name(i):
            missing.append(i)
        else:
            base = kept[-1]
    loaded, _ = checkpoint.load(list_checkpoints(directory)[-1])
    same = all(torch.equal(loaded["net"][k], v) for k, v in state["net"].items())
    print(f"inside {inside} missing {missing} same {same}")
    """
)


def test_ctrl_c_at_any_moment_of_checkpoints_never_loses_one_or_aborts(tmp_path):
    """30 checkpoints, each with a real SIGINT at a random moment of its write: every one is
    written whole, the process goes on (no `terminate called ...`), the last one loads."""
    done = subprocess.run(
        [sys.executable, "-c", SIGNALS_AT_RANDOM, str(tmp_path / "checkpoints")],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert done.returncode == 0, done.stderr[-3000:]
    words = done.stdout.split()
    assert words[2:] == ["missing", "[]", "same", "True"], done.stdout
    assert int(words[1]) >= 10, done.stdout  # the signals came while checkpoints were written
