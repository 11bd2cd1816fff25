"""How the bake's processes talk: one message format over a pipe, and one way for a child
process to end as soon as its parent is gone.

The processes are the helper that works the second core (`parallel.Helper`, over a
`multiprocessing` connection) and the worker processes Blender starts for the bake and
the live preview (over their standard streams, `Stream`). Each pipe carries messages,
any picklable object, in frames (`send`, `receive`):

1. the sizes of the message's out-of-band buffers (a pickled list);
2. the pickle itself (protocol 5), which holds only the arrays' shapes and types;
3. each array's memory as it lies, a frame per buffer, read into the buffer the rebuilt
   array then uses.

A plain `Connection.send` pickles everything into one bytes object first, and `recv`
reads one back before unpickling: a copy of all the arrays on each side, for as long as
the transfer takes (1.3 GB for a 256-cell bake's in-betweens).

Pickles name the package's classes by the sender's package name: in an installed
extension ``bl_ext.user_default.keyframe_implicit``, in the worker it starts
``keyframe_implicit``. `receive` maps them onto the receiver's own (``rename``).

A child reads its parent's end of a pipe until it closes (`follow_parent`) and then ends
at once: a parent killed outright (a cancelled bake's worker, or Blender itself) takes its
children with it, and none works on for nobody.
"""

from __future__ import annotations

import contextlib
import io
import os
import pickle
import struct
import threading
import traceback
from collections.abc import Callable
from typing import Any, BinaryIO, Protocol

__all__ = ["Connection", "Stream", "send", "receive", "follow_parent"]

#: A `Stream` frame's header: its length in bytes.
_LENGTH = struct.Struct("<Q")


class Connection(Protocol):
    """What `send` and `receive` need of a pipe: a `multiprocessing` connection's byte
    frames (a `multiprocessing.connection.Connection`, or a `Stream`)."""

    def send_bytes(self, buf: Any) -> None: ...

    def recv_bytes(self) -> bytes | bytearray: ...

    def recv_bytes_into(self, buf: Any) -> int: ...


class Stream:
    """A connection over a pair of binary files, a child process's standard streams: each
    frame is its length (8 bytes, little-endian) and then its bytes.

    Parameters
    ----------
    reader, writer : binary file, optional
        Where frames come from and go to (a `subprocess.Popen`'s ``stdout`` and ``stdin``
        in the parent; in the child, unbuffered files on its standard input and output,
        so that a thread blocked reading holds no buffer's lock at the interpreter's exit).
        A write to a process that has ended raises `BrokenPipeError`, a read at the end of
        the stream `EOFError`, and one on a closed file `ValueError`.

    Attributes
    ----------
    lock : threading.Lock
        Held by `send` for a whole message, so that messages sent from several threads
        (the bake's progress, reported from the threads of its two maps) go whole.
    """

    def __init__(self, reader: BinaryIO | None = None,
                 writer: BinaryIO | None = None) -> None:
        self.reader, self.writer = reader, writer
        self.lock = threading.Lock()

    def send_bytes(self, buf: Any) -> None:
        """Write one frame holding ``buf`` (any buffer) and flush it."""
        view = memoryview(buf).cast("B")
        self._write(memoryview(_LENGTH.pack(view.nbytes)))
        self._write(view)
        self.writer.flush()

    def recv_bytes(self) -> bytearray:
        """The next frame's bytes; EOFError at the end of the stream."""
        data = bytearray(self._length())
        self._read_into(memoryview(data))
        return data

    def recv_bytes_into(self, buf: Any) -> int:
        """Read the next frame into ``buf`` (writable, at least as large); its length."""
        n, view = self._length(), memoryview(buf).cast("B")
        if n > view.nbytes:
            raise ValueError(f"a frame of {n} bytes does not fit a buffer of {view.nbytes}")
        self._read_into(view[:n])
        return n

    def _length(self):
        header = bytearray(_LENGTH.size)
        self._read_into(memoryview(header))
        return _LENGTH.unpack(header)[0]

    def _write(self, view):
        while view.nbytes:  # an unbuffered file may take part of it
            view = view[self.writer.write(view):]

    def _read_into(self, view):
        while view.nbytes:
            got = self.reader.readinto(view)
            if not got:
                raise EOFError("the stream has ended")
            view = view[got:]


def send(conn: Connection, obj: Any) -> None:
    """Send ``obj`` over ``conn``, its arrays' memory out of band (module docstring).
    Pickling happens before anything is sent, so a failure leaves the pipe clean. A
    `Stream` takes messages from several threads; a `multiprocessing` connection, from
    one at a time."""
    buffers = []
    head = pickle.dumps(obj, protocol=5, buffer_callback=buffers.append)
    raw = [b.raw() for b in buffers]
    with conn.lock if isinstance(conn, Stream) else contextlib.nullcontext():
        conn.send_bytes(pickle.dumps([r.nbytes for r in raw]))
        conn.send_bytes(head)
        for r in raw:
            conn.send_bytes(r)


def receive(conn: Connection, rename: tuple[str, str] | None = None) -> Any:
    """The object `send` sent: each buffer read into a bytearray its array then uses.

    ``rename`` = (the sender's package name, this one's): classes of the sender's package
    are found in this one's. EOFError at the end of the pipe.
    """
    sizes = pickle.loads(conn.recv_bytes())
    head = conn.recv_bytes()
    buffers = [bytearray(n) for n in sizes]
    for b in buffers:
        conn.recv_bytes_into(b)
    if rename is None:
        return pickle.loads(head, buffers=buffers)
    return _Renaming(io.BytesIO(head), rename, buffers).load()


class _Renaming(pickle.Unpickler):
    def __init__(self, file, rename, buffers):
        super().__init__(file, buffers=buffers)
        self._sender, self._own = rename

    def find_class(self, module, name):
        if module == self._sender or module.startswith(self._sender + "."):
            module = self._own + module[len(self._sender):]
        return super().find_class(module, name)


def follow_parent(conn: Connection, take: Callable[[Any], object] | None = None,
                  rename: tuple[str, str] | None = None, code: int = 1) -> None:
    """In a child process: a daemon thread reads its parent's messages from ``conn``,
    handing each to ``take`` (a parent that only holds its end sends none), and ends this
    process at once, with exit status ``code``, when the parent's end closes (the parent
    has gone, or closed it). A message that cannot be read or taken ends it too, its
    traceback on stderr: a child that no longer follows its parent would work on for
    nobody, and its parent would wait for an answer that never comes. ``rename`` as in
    `receive`."""

    def follow():
        try:
            while True:
                message = receive(conn, rename)
                if take is not None:
                    take(message)
        except (EOFError, OSError):
            pass  # the parent's end closed
        except BaseException:
            traceback.print_exc()
        finally:
            os._exit(code)

    threading.Thread(target=follow, daemon=True, name="keyframe_implicit parent").start()
