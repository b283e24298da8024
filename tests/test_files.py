"""Files replaced whole (qfg.files): a failed or interrupted write leaves the old file as it was.
Fault injection: an exception in the writer, a file size limit (RLIMIT_FSIZE) and a full device
(/dev/full) in the writing process, and SIGKILL in the middle of a write."""

import os
import signal
import stat
import subprocess
import sys
import time

import pytest

from qfg.files import atomic_write_bytes, atomic_write_text, atomic_writer

posix = pytest.mark.skipif(os.name != "posix", reason="POSIX resource limits and signals")


def _leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


def test_writes_and_replaces(tmp_path):
    p = tmp_path / "r.txt"
    atomic_write_text(p, "one\n")
    inode = p.stat().st_ino
    atomic_write_text(p, "two\n")
    assert p.read_text() == "two\n" and _leftovers(tmp_path) == []
    assert p.stat().st_ino != inode           # a new file renamed over the old: never truncated
    atomic_write_bytes(p, b"\x00\x01")
    assert p.read_bytes() == b"\x00\x01"


def test_an_exception_while_writing_keeps_the_old_file(tmp_path):
    p = tmp_path / "r.txt"
    p.write_text("old result\n")
    with pytest.raises(RuntimeError):
        with atomic_writer(p) as f:
            f.write("part of the new")
            f.flush()
            raise RuntimeError("the writer failed")
    assert p.read_text() == "old result\n" and _leftovers(tmp_path) == []


@posix
def test_permissions_follow_the_umask_or_the_old_file(tmp_path):
    old = os.umask(0o027)
    try:
        atomic_write_text(tmp_path / "new.txt", "x")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "new.txt").stat().st_mode) == 0o640   # not mkstemp's 0o600
    p = tmp_path / "kept.txt"
    p.write_text("x")
    p.chmod(0o604)
    atomic_write_text(p, "y")
    assert stat.S_IMODE(p.stat().st_mode) == 0o604


@posix
def test_a_link_is_replaced_never_written_through(tmp_path):
    """A link planted where an output goes: the output replaces it, its target untouched (the
    rule of the experiment runner's outputs)."""
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    victim.chmod(0o600)
    link = tmp_path / "out.txt"
    link.symlink_to(victim)
    mask = os.umask(0o022)
    try:
        atomic_write_text(link, "new")
    finally:
        os.umask(mask)
    assert not link.is_symlink() and link.read_text() == "new"
    assert victim.read_text() == "precious\n"
    assert stat.S_IMODE(link.stat().st_mode) == 0o644          # the target's mode not passed on
    dangling = tmp_path / "dangling.txt"
    dangling.symlink_to(tmp_path / "nowhere")
    atomic_write_text(dangling, "x")
    assert dangling.read_text() == "x" and not (tmp_path / "nowhere").exists()


@posix
def test_a_link_to_a_device_writes_to_the_device(tmp_path):
    link = tmp_path / "null"
    link.symlink_to(os.devnull)
    atomic_write_text(link, "discarded")
    assert link.is_symlink() and stat.S_ISCHR(os.stat(link).st_mode)


@pytest.mark.parametrize("where, error", [
    (lambda d: d, IsADirectoryError),
    (lambda d: d / "file.txt" / "r.txt", NotADirectoryError),
    (lambda d: d / "missing" / "r.txt", FileNotFoundError),
])
def test_bad_targets_are_os_errors_naming_the_target(tmp_path, where, error):
    (tmp_path / "file.txt").write_text("keep")
    target = where(tmp_path)
    with pytest.raises(error) as info:
        atomic_write_text(target, "x")
    assert info.value.filename == str(target)
    assert (tmp_path / "file.txt").read_text() == "keep" and _leftovers(tmp_path) == []


@posix
@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")
def test_a_device_is_written_to_not_replaced():
    """Renaming a temporary file onto /dev/full (possible as root) would swap the device for a
    regular file and report success: the data goes to the device, and its error is raised."""
    before = set(os.listdir("/dev"))
    atomic_write_text("/dev/null", "discarded\n")
    with pytest.raises(OSError) as info:
        atomic_write_text("/dev/full", "x" * 100_000)
    assert info.value.errno == 28 and info.value.filename == "/dev/full"      # ENOSPC
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode)
    assert set(os.listdir("/dev")) == before


CHILD_FSIZE = """
import resource, sys
from qfg.files import atomic_write_text
resource.setrlimit(resource.RLIMIT_FSIZE, (20, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
try:
    atomic_write_text(sys.argv[1], "new result " * 1000)
except OSError as exc:
    print(f"{type(exc).__name__} {exc.errno} {exc.filename}")
    sys.exit(3)
"""


@posix
def test_a_file_size_limit_keeps_the_old_file(tmp_path):
    """The write fails after 20 bytes: the old result stays whole and no fragment is left."""
    p = tmp_path / "r.txt"
    p.write_text("the old result, longer than twenty bytes\n")
    r = subprocess.run([sys.executable, "-c", CHILD_FSIZE, str(p)], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 3, r.stderr
    assert r.stdout.split() == ["OSError", "27", str(p)]                       # EFBIG
    assert p.read_text() == "the old result, longer than twenty bytes\n"
    assert _leftovers(tmp_path) == []


CHILD_SLOW = """
import sys, time
from qfg.files import atomic_writer
with atomic_writer(sys.argv[1]) as f:
    f.write("new " * 100_000)
    f.flush()
    print("writing", flush=True)
    time.sleep(60)
    f.write("end")
"""


@posix
def test_sigkill_in_the_middle_of_a_write_keeps_the_old_file(tmp_path):
    p = tmp_path / "r.txt"
    p.write_text("old\n")
    child = subprocess.Popen([sys.executable, "-c", CHILD_SLOW, str(p)], stdout=subprocess.PIPE,
                             text=True)
    try:
        assert child.stdout.readline() == "writing\n"
        child.send_signal(signal.SIGKILL)
        child.wait(timeout=30)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    child.stdout.close()
    assert p.read_text() == "old\n"
    assert len(_leftovers(tmp_path)) == 1      # only a kill outright can leave the temporary file


CHILD_LOOP = """
import sys
from qfg.files import atomic_write_text
texts = ["a" * 300_000, "b" * 200_000]
i = 0
while True:
    atomic_write_text(sys.argv[1], texts[i % 2])
    i += 1
    if i == 3:
        print("running", flush=True)
"""


@posix
@pytest.mark.parametrize("delay", [0.0, 0.01, 0.03, 0.1])
def test_sigkill_at_any_moment_leaves_one_whole_version(tmp_path, delay):
    p = tmp_path / "r.txt"
    child = subprocess.Popen([sys.executable, "-c", CHILD_LOOP, str(p)], stdout=subprocess.PIPE,
                             text=True)
    try:
        assert child.stdout.readline() == "running\n"
        time.sleep(delay)
        child.send_signal(signal.SIGKILL)
        child.wait(timeout=30)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    child.stdout.close()
    assert p.read_text() in ("a" * 300_000, "b" * 200_000)


def test_mode_is_checked(tmp_path):
    with pytest.raises(ValueError, match="mode"):
        with atomic_writer(tmp_path / "x", "a"):
            pass


def test_write_uai_and_write_result_replace_whole(tmp_path):
    """The library's writers use the helper: the folder of a result is created, a result under
    a file is an OSError naming it."""
    import numpy as np

    from qfg.inference import FactorModel, solve_task, write_uai
    from qfg.inference.tasks import write_result

    model = FactorModel([2], [(0,)], [np.array([0.25, 0.75])])
    write_uai(model, tmp_path / "m.uai")
    first = (tmp_path / "m.uai").stat().st_ino
    write_uai(model, tmp_path / "m.uai")
    assert (tmp_path / "m.uai").stat().st_ino != first and _leftovers(tmp_path) == []
    r = solve_task(model, "PR")
    out = write_result(r, tmp_path / "new" / "m.PR")
    assert out.read_text() == r.to_text()
    with pytest.raises(NotADirectoryError, match="is a file") as info:
        write_result(r, tmp_path / "m.uai" / "m.PR")
    assert info.value.filename == str(tmp_path / "m.uai" / "m.PR")
