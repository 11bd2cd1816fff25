"""The bake's processes' one message format over a child's standard streams (`wire.Stream`),
and a child following its parent (`wire.follow_parent`)."""

import os
import pickle
import subprocess
import sys
import threading

import numpy as np
import pytest

from keyframe_implicit.core.base.grid import Grid
from keyframe_implicit.core.base.wire import Stream, receive, send

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.fixture
def pipe():
    """A Stream's two ends over an OS pipe: (sending end, receiving end), unbuffered as a
    worker's own are."""
    r, w = os.pipe()
    reader, writer = open(r, "rb", buffering=0), open(w, "wb", buffering=0)
    yield Stream(writer=writer), Stream(reader=reader)
    writer.close()
    reader.close()


def test_arrays_cross_a_stream_out_of_band_and_arrive_writable(pipe):
    mine, theirs = pipe
    frames = []
    mine_send_bytes = mine.send_bytes

    def spy(buf):  # records the size of each frame
        frames.append(memoryview(buf).nbytes)
        mine_send_bytes(buf)

    mine.send_bytes = spy
    big = np.random.default_rng(2).random((400, 300))  # larger than a pipe's buffer
    obj = dict(big=big, strided=big[:, ::2], empty=np.zeros((0, 3)), text="frame 3")
    thread = threading.Thread(target=send, args=(mine, obj))
    thread.start()
    got = receive(theirs)
    thread.join()
    assert sorted(frames[2:]) == sorted(obj[k].nbytes for k in ("big", "empty"))
    assert got.keys() == obj.keys() and got["text"] == "frame 3"
    for key in ("big", "strided", "empty"):
        assert np.array_equal(got[key], obj[key]) and got[key].flags.writeable, key


def test_a_senders_package_name_is_read_as_the_receivers(pipe):
    """An installed extension's classes are named ``bl_ext.user_default.keyframe_implicit...``;
    the worker's, ``keyframe_implicit...``: each reads the other's as its own."""
    mine, theirs = pipe
    grid = Grid((0.0, 1.0, 2.0), 0.5, (3, 4, 5))
    sender = "bl_ext.user_a.kfi"  # as long as the name it stands for: the pickle stays valid
    head = pickle.dumps(grid, protocol=5).replace(b"keyframe_implicit", sender.encode())
    assert sender.encode() in head and b"keyframe_implicit" not in head
    mine.send_bytes(pickle.dumps([]))
    mine.send_bytes(head)
    assert receive(theirs, (sender, "keyframe_implicit")) == grid
    mine.send_bytes(pickle.dumps([]))
    mine.send_bytes(head)
    with pytest.raises(ModuleNotFoundError):
        receive(theirs)


def test_messages_sent_from_several_threads_arrive_whole(pipe):
    """The worker reports progress from the threads of both maps: each message goes whole."""
    mine, theirs = pipe
    count, threads = 200, 4

    def report(k):
        for i in range(count):
            send(mine, ("progress", k, i, np.full(64, i, dtype=np.int64)))

    senders = [threading.Thread(target=report, args=(k,)) for k in range(threads)]
    for t in senders:
        t.start()
    seen = {k: [] for k in range(threads)}
    for _ in range(count * threads):
        _, k, i, values = receive(theirs)
        assert np.all(values == i)
        seen[k].append(i)
    for t in senders:
        t.join()
    assert all(seen[k] == list(range(count)) for k in range(threads))


def test_the_end_of_a_stream_is_eof(pipe):
    mine, theirs = pipe
    send(mine, "last")
    mine.writer.close()
    assert receive(theirs) == "last"
    with pytest.raises(EOFError):
        receive(theirs)


CHILD = """
import time
from keyframe_implicit.core.base.wire import Stream, follow_parent
follow_parent(Stream(open(0, "rb", buffering=0, closefd=False)), print, code=3)
print("following", flush=True)
time.sleep(120)
"""


def test_a_child_ends_at_once_with_its_parents_end():
    child = subprocess.Popen([sys.executable, "-c", CHILD], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, text=False,
                             env=dict(os.environ, PYTHONPATH=ROOT))
    try:
        assert child.stdout.readline() == b"following\n"
        send(Stream(writer=child.stdin), "a message it takes")
        assert child.stdout.readline() == b"a message it takes\n"
        child.stdin.close()  # the parent's end closes: the child ends, not sleeps on
        assert child.wait(30) == 3
    finally:
        child.kill()
        child.wait()


FAILING_CHILD = """
import time
from keyframe_implicit.core.base.wire import Stream, follow_parent
def take(message):
    raise RuntimeError(f"cannot take {message!r}")
follow_parent(Stream(open(0, "rb", buffering=0, closefd=False)), take, code=3)
print("following", flush=True)
time.sleep(120)
"""


def test_a_child_that_cannot_take_a_message_ends_and_says_why():
    """Not a follower thread dead and a child working on for nobody: it ends at once."""
    child = subprocess.Popen([sys.executable, "-c", FAILING_CHILD], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=False,
                             env=dict(os.environ, PYTHONPATH=ROOT))
    try:
        assert child.stdout.readline() == b"following\n"
        send(Stream(writer=child.stdin), "a message it cannot take")
        assert child.wait(30) == 3  # the parent's end is still open
        assert b"cannot take 'a message it cannot take'" in child.stderr.read()
    finally:
        child.kill()
        child.wait()
