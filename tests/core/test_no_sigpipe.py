"""Writing to a worker that has ended must not end Blender: its embedded interpreter leaves
SIGPIPE at the default action (ending the process), where python ignores it."""

import os
import signal
import subprocess
import sys

import pytest

SNIPPET = """
import signal, subprocess, sys
signal.signal(signal.SIGPIPE, signal.SIG_DFL)  # as in Blender
from keyframe_implicit.worker import no_sigpipe
ended = subprocess.Popen([sys.executable, "-c", "pass"], stdin=subprocess.PIPE)
ended.wait()
guard = no_sigpipe() if sys.argv[1] == "guarded" else open(__file__)
try:
    with guard:
        ended.stdin.write(b"x" * 100000)
        ended.stdin.flush()
except BrokenPipeError:
    print("BrokenPipeError")
"""


@pytest.mark.skipif(not hasattr(signal, "SIGPIPE"), reason="Windows has no SIGPIPE")
@pytest.mark.parametrize("how", ["guarded", "bare"])
def test_a_write_to_an_ended_worker_is_an_error_not_the_end_of_the_process(how, tmp_path):
    script = tmp_path / "write.py"
    script.write_text(SNIPPET)
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    done = subprocess.run([sys.executable, str(script), how], capture_output=True, text=True,
                          env=dict(os.environ, PYTHONPATH=root))
    if how == "guarded":
        assert done.returncode == 0 and "BrokenPipeError" in done.stdout
    else:  # what Blender did before: ended by the signal
        assert done.returncode == -signal.SIGPIPE
