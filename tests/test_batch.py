"""``hyperlf batch`` (issue 13 item 4): many captures on a dask LocalCluster, whole result sets,
a worker killed mid-run, re-runs that recompute nothing, failures in the summary."""

import csv
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed", reason="hyperlf batch needs the optional dask.distributed "
                                          "(pip install 'hyperlf[batch]')")

from hyperlf import batch  # noqa: E402
from hyperlf.errors import DataNotFoundError, InvalidInputError  # noqa: E402
from hyperlf.formats import load_lightfield, read_pfm, save_lightfield  # noqa: E402
from hyperlf.outputs import MANIFEST  # noqa: E402

LABELS = 12


@pytest.fixture(scope="module")
def captures(tmp_path_factory):
    from hyperlf import synthesis

    root = tmp_path_factory.mktemp("frames")
    for seed in range(4):
        lf = synthesis.procedural_scene(seed=seed, rows=3, cols=3, height=40, width=56,
                                        texture_scale=2.5)
        save_lightfield(lf, root / f"frame{seed}")
    return root


def _hyperlf(*argv, **kw):
    return subprocess.Popen([sys.executable, "-m", "hyperlf", *map(str, argv)],
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kw)


def _children() -> dict[int, list[int]]:
    """Parent pid -> child pids of every process (Linux /proc)."""
    kids: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        kids.setdefault(ppid, []).append(int(entry))
    return kids


def _descendants(pid: int) -> list[int]:
    kids, out, todo = _children(), [], [pid]
    while todo:
        for c in kids.get(todo.pop(), []):
            out.append(c)
            todo.append(c)
    return out


def _cmdline(pid: int) -> list[str]:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace").split("\0")
    except OSError:
        return []


def _running_depth(batch_pid: int, timeout: float = 120.0):
    """``(depth pid, its worker's pid, capture)`` of a capture the batch is running."""
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        for pid in _depth_processes(batch_pid):
            cmd = _cmdline(pid)
            stat = Path(f"/proc/{pid}/stat").read_text()
            worker = int(stat.rsplit(")", 1)[1].split()[1])
            return pid, worker, cmd[cmd.index("depth") + 1]
        time.sleep(0.02)
    raise AssertionError("the batch never started a depth process")


def _depth_processes(batch_pid: int) -> list[int]:
    """The pids of every depth process the batch is running now."""
    return [pid for pid in _descendants(batch_pid)
            if "hyperlf" in (cmd := _cmdline(pid)) and "depth" in cmd]


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (neither gone nor a zombie)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _summary(out: Path) -> list[dict]:
    with open(out / "summary.csv", newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def _assert_whole(folder: Path) -> None:
    listed = set(json.loads((folder / MANIFEST).read_text())["files"])
    present = {p.name for p in folder.iterdir()} - {MANIFEST}
    assert listed == present and "disparity.pfm" in present


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="finds workers in /proc")
def test_a_killed_worker_loses_no_capture_and_a_rerun_recomputes_nothing(captures, tmp_path):
    from hyperlf.hlf import depth

    out = tmp_path / "out"
    proc = _hyperlf("batch", captures, "--labels", LABELS, "--workers", 2, "-o", out)
    try:
        depth_pid, worker, capture = _running_depth(proc.pid)
        os.kill(worker, signal.SIGKILL)  # mid-run: its capture is being matched
        _, err = proc.communicate(timeout=300)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    time.sleep(0.2)
    assert not Path(f"/proc/{depth_pid}").exists() or \
        "Z" in Path(f"/proc/{depth_pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    rows = _summary(out)
    assert [r["capture"] for r in rows] == [f"frame{s}" for s in range(4)]
    assert all(r["status"] == "done" for r in rows), rows
    assert not [p for p in out.iterdir() if p.name.endswith(".new")]  # no staging left
    for s in range(4):
        folder = out / f"frame{s}"
        _assert_whole(folder)
        expected = depth(load_lightfield(captures / f"frame{s}"), n_labels=LABELS).disparity
        assert np.array_equal(read_pfm(folder / "disparity.pfm"), expected), folder
        assert float(rows[s]["rmse_px"]) >= 0
    assert Path(capture).name in {f"frame{s}" for s in range(4)}
    assert (out / "summary.html").read_text().count("<tr") == 5

    stamps = {p: p.stat().st_mtime_ns for p in out.glob("frame*/disparity.pfm")}
    again = _hyperlf("-q", "batch", captures, "--labels", LABELS, "--workers", 2, "-o", out)
    _, err = again.communicate(timeout=120)
    assert again.returncode == 0, err
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps  # nothing recomputed
    assert all(r["status"] == "done before" for r in _summary(out))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="finds workers in /proc")
def test_sigterm_to_a_batch_leaves_no_hidden_staging_folders(captures, tmp_path):
    """The depth processes of a stopped batch get SIGTERM when their worker goes (they used to
    get SIGKILL and leave their staging folders until the next run) and clean up themselves."""
    out = tmp_path / "out"
    proc = _hyperlf("batch", captures, "--labels", LABELS, "--workers", 2, "-o", out)
    try:
        _running_depth(proc.pid)
        depth_pids = _depth_processes(proc.pid)  # with 2 workers there may be two
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 143, err
    assert "terminated" in err and "Traceback" not in err
    t_end = time.monotonic() + 60  # each depth process cleans up after its worker has gone
    for pid in depth_pids:
        while _alive(pid) and time.monotonic() < t_end:
            time.sleep(0.05)
    if not out.exists():  # stopped before its first result: the folder it made is gone
        return
    hidden = lambda: [p.name for p in out.iterdir() if p.name.startswith(".hyperlf-")]  # noqa: E731
    # a depth process started just as the signal came is not among depth_pids; its staging
    # names carry its pid: wait for it too (a fresh clone's first run compiles the numba
    # kernels, so it may react late), up to 120 s more
    t_end = max(t_end, time.monotonic() + 120)
    writers = lambda names: {int(n.split("-")[1]) for n in names  # noqa: E731
                             if n.split("-")[1].isdigit()}
    while hidden() not in ([], [".hyperlf-batch.json"]) and time.monotonic() < t_end:
        pids = writers(hidden())
        if pids and not any(_alive(pid) for pid in pids):
            time.sleep(0.5)  # gone: give the file system a moment, then judge
            break
        time.sleep(0.05)
    left = hidden()
    alive = [pid for pid in writers(left) if _alive(pid)]
    assert left in ([], [".hyperlf-batch.json"]), (left, "writers still running:", alive)
    for folder in (p for p in out.iterdir() if p.is_dir()):
        _assert_whole(folder)  # what finished before the signal is whole


def test_ctrl_c_to_the_whole_process_group_prints_no_worker_traceback(captures, tmp_path):
    """A terminal's Ctrl-C reaches every process of the group, the dask workers too: they
    ignore it (this process closes the cluster), so one line is printed, not their
    tracebacks."""
    out = tmp_path / "out"
    proc = _hyperlf("batch", captures, "--labels", LABELS, "--workers", 1, "-o", out,
                    start_new_session=True)
    try:
        _running_depth(proc.pid)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert not list(out.glob(batch.SCRATCH_PREFIX + "*"))


def test_a_failed_capture_is_reported_and_the_others_finish(captures, tmp_path):
    import shutil

    frames = tmp_path / "frames"
    for s in (0, 1):
        shutil.copytree(captures / f"frame{s}", frames / f"frame{s}")
    view = frames / "frame1" / "view_r0_c0.png"
    view.write_bytes(view.read_bytes()[:200])  # a truncated image
    out = tmp_path / "out"
    proc = _hyperlf("batch", frames, "--labels", LABELS, "--workers", 1, "-o", out)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 1
    assert "1 of 2 captures failed" in err.splitlines()[-1]
    rows = {r["capture"]: r for r in _summary(out)}
    assert rows["frame0"]["status"] == "done" and rows["frame1"]["status"] == "failed"
    assert rows["frame1"]["exit_code"] == "3" and "view_r0_c0.png" in rows["frame1"]["message"]
    assert not (out / "frame1").exists()
    _assert_whole(out / "frame0")
    from hyperlf.formats import describe  # what 'hyperlf info OUT' prints
    text = describe(out)
    assert text.startswith("batch output: 2 captures (1 done, 1 failed)")
    assert "frame1: failed (" in text


# ----------------------------------------------------------------------------- planning
def test_find_captures_takes_folders_patterns_and_files(captures, tmp_path):
    found = batch.find_captures([captures])
    assert [p.name for p in found] == [f"frame{s}" for s in range(4)]
    assert batch.find_captures([str(captures / "frame[12]")]) == found[1:3]
    assert batch.find_captures([captures / "frame2", captures]) == [found[2], *found[:2],
                                                                     found[3]]
    h5 = tmp_path / "one.h5"
    save_lightfield(load_lightfield(captures / "frame0"), h5)
    assert batch.find_captures([h5]) == [h5.resolve()]
    with pytest.raises(DataNotFoundError, match="no such"):
        batch.find_captures([tmp_path / "missing"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(DataNotFoundError, match="no capture"):
        batch.find_captures([tmp_path / "empty"])


@pytest.mark.parametrize("recorded, shown", [
    ([1, 2], "([1, 2])"), (["--labels", "a\nb"], "(--labels a b)"), (None, "(none)"),
    ("x", "('x')"), (["--labels", "8"], "(--labels 8)")])
def test_a_marker_edited_by_hand_is_named_in_one_line(captures, tmp_path, recorded, shown):
    """A batch folder's marker holding anything as its options: refused in one line that
    shows them (a list of numbers raised TypeError in the message's join)."""
    import json

    out = tmp_path / "out"
    (out / "frame0").mkdir(parents=True)   # a result: the recorded options bind
    (out / batch.BATCH_FILE).write_text(json.dumps({"depth_args": recorded}))
    with pytest.raises(InvalidInputError) as exc:
        batch.plan_batch([captures], out, depth_args=["--labels", "9"])
    assert f"made with other depth options {shown};" in str(exc.value)
    assert "\n" not in str(exc.value)


def test_output_names_are_unique():
    paths = [Path("a/x"), Path("b/x"), Path("c/x.h5"), Path("d/y.h5"), Path("e/.h5")]
    assert batch._names(paths) == ["x", "x-2", "x-3", "y", "capture"]


def test_a_batch_folder_records_its_options(captures, tmp_path):
    out = tmp_path / "out"
    tasks = batch.plan_batch([captures], out, depth_args=["--labels", "8"])
    assert [t.name for t in tasks] == [f"frame{s}" for s in range(4)]
    assert all(Path(t.output).parent == out for t in tasks)
    batch.plan_batch([captures], out, depth_args=["--labels", "8"])  # same options: fine
    # nothing computed yet (an unreachable scheduler): other options are free to start
    batch.plan_batch([captures], out, depth_args=["--labels", "7"])
    batch.plan_batch([captures], out, depth_args=["--labels", "8"])
    (out / "frame0").mkdir()   # a capture's results: now the options bind
    with pytest.raises(InvalidInputError, match="other depth options"):
        batch.plan_batch([captures], out, depth_args=["--labels", "9"])
    tasks = batch.plan_batch([captures], out, depth_args=["--labels", "9"], overwrite=True)
    assert all(t.overwrite for t in tasks)
    with pytest.raises(InvalidInputError, match="did not finish"):  # old results may remain
        batch.plan_batch([captures], out, depth_args=["--labels", "9"])
    done = [batch.CaptureResult(t.name, t.capture, "done") for t in tasks]
    batch.finish_batch(out, done[:1] + [batch.CaptureResult("x", "x", "failed")])
    with pytest.raises(InvalidInputError, match="did not finish"):
        batch.plan_batch([captures], out, depth_args=["--labels", "9"])
    batch.finish_batch(out, done)
    batch.plan_batch([captures], out, depth_args=["--labels", "9"])  # now whole again
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(InvalidInputError, match="not a hyperlf batch"):
        batch.plan_batch([captures], tmp_path / "mine")
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep"


def test_a_batch_disparity_range_reaches_every_depth_run(captures, tmp_path):
    tasks = batch.plan_batch([captures], tmp_path / "out", depth_args=["--labels", "8"],
                             disparity_range=(-1.5, 2.0))
    assert all(t.depth_args == ("--disparity-range=-1.5,2", "--labels", "8") for t in tasks)
    assert all(t.disparity_range == (-1.5, 2.0) for t in tasks)


def test_a_downscaled_batch_is_measured_at_its_own_resolution(tmp_path):
    """``--downscale`` reaches every depth run and the measuring of its results: the scores
    are those of the half-size map against the half-size truth, as depth itself prints."""
    from hyperlf import metrics, synthesis
    from hyperlf.lightfield import downscale

    big = tmp_path / "big"  # large enough to be scored at half size (HCI's 15 px border)
    save_lightfield(synthesis.procedural_scene(seed=7, rows=3, cols=3, height=76, width=84,
                                               texture_scale=2.5), big / "frame")
    out = tmp_path / "out"
    tasks = batch.plan_batch([big], out, depth_args=["--labels", "8"], downscale=2)
    assert tasks[0].depth_args == ("--downscale=2", "--labels", "8")
    row = batch.run_capture(tasks[0])
    assert row.status == "done", row.message
    d = read_pfm(Path(tasks[0].output) / "disparity.pfm")
    small = downscale(load_lightfield(tasks[0].capture, cube=False), 2, truth=True)
    assert d.shape == small.image_shape == (38, 42)
    want = metrics.hci_scores(d, small.reference_gt_disparity)
    assert row.rmse_px == round(float(want.rmse), 5) and np.isfinite(row.rmse_px)
    at = metrics.at_range_limit(d, small.disparity_range)
    assert row.range_limit_pct == round(100.0 * float(at.mean()), 3)
    with pytest.raises(InvalidInputError, match="other depth options"):
        batch.plan_batch([big], out, depth_args=["--labels", "8"])  # not silently mixed


def test_output_names_never_collide_nor_take_the_summary_names():
    names = batch._names([Path("A/x"), Path("B/x"), Path("B/x-2"), Path("c/summary.html"),
                          Path("d/x.h5")])
    assert len(set(names)) == 5 and names[2] == "x-2" and names[3] != "summary.html"
    assert names[0] == "x"


def test_a_batch_that_fails_before_its_first_capture_leaves_no_folder(captures, tmp_path):
    from hyperlf.cli import main

    out = tmp_path / "never"
    assert main(["-q", "batch", str(captures / "frame0"), "--scheduler", "tcp://127.0.0.1:1",
                 "-o", str(out)]) == 2
    assert not out.exists()
    assert main(["-q", "batch", str(captures / "frame0"), "-o", str(captures / "frame0")]) == 2


def test_a_batch_runs_on_a_scheduler_that_is_already_there(captures, tmp_path):
    """``--scheduler``: a batch runs on a cluster that is already there, and an address
    nothing listens at is refused at once, not after the client's 20 s of retries."""
    import dask
    from dask.distributed import LocalCluster

    from hyperlf.cli import main

    scratch = {"temporary-directory": str(tmp_path)}  # not dask's default, $TMPDIR
    with dask.config.set(scratch), LocalCluster(
            n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None,
            scheduler_kwargs=batch._PRIVATE_HTTP) as cluster:
        out = tmp_path / "b"
        assert main(["-q", "batch", str(captures / "frame1"), "--labels", str(LABELS),
                     "--scheduler", cluster.scheduler_address, "-o", str(out)]) == 0
        assert (out / "frame1" / "disparity.pfm").is_file()
    with socket.socket() as free:  # a port nothing listens at
        free.bind(("127.0.0.1", 0))
        port = free.getsockname()[1]
    start = time.monotonic()
    with pytest.raises(ConnectionRefusedError):
        batch._connect_once(f"tcp://127.0.0.1:{port}")
    assert time.monotonic() - start < 5
    batch._connect_once("inproc://nothing-to-open")  # left to dask


def test_the_local_schedulers_http_server_is_private_and_takes_a_free_port(tmp_path):
    """Two local clusters at once (two batches): each scheduler's HTTP server listens on this
    machine only, on a port of its own, without the warning that port 8787 is in use."""
    import warnings

    clusters = []
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            for k in range(2):
                (tmp_path / str(k)).mkdir()
                clusters.append(batch._client(1, None, tmp_path / str(k)))
        socks = [s.getsockname() for _, c in clusters
                 for s in c.scheduler.http_server._sockets.values()]
        assert {host for host, _ in socks} == {"127.0.0.1"}
        assert len({port for _, port in socks}) == 2
    finally:
        for client, cluster in clusters:
            client.close()
            cluster.close()


def test_a_local_cluster_keeps_its_scratch_inside_the_batch_folder(captures, tmp_path,
                                                                    monkeypatch):
    seen = {}
    real = batch._client

    def spy(workers, scheduler, scratch=None):
        seen["scratch"] = scratch
        return real(workers, scheduler, scratch)

    monkeypatch.setattr(batch, "_client", spy)
    system = tmp_path / "system-temp"  # the scheduler's scratch went there (dask's default)
    system.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(system))
    tasks = batch.plan_batch([captures / "frame0"], tmp_path / "b",
                             depth_args=["--labels", str(LABELS)])
    stale = tmp_path / "b" / f"{batch.SCRATCH_PREFIX}999999999-x"
    stale.mkdir()  # a killed run's (no such process)
    rows = batch.run_batch(tasks, workers=1, progress=False)
    assert rows[0].status == "done"
    assert seen["scratch"].parent == tmp_path / "b"
    assert not seen["scratch"].exists() and not stale.exists()
    assert list(system.iterdir()) == []
