"""The ``wrt`` command's process entry point (``wrt``, ``python -m wrt``).

It imports nothing but ``signal`` and ``sys`` before it takes Ctrl-C and SIGTERM in hand, so that
a signal at any moment of start-up (while ``wrt.cli``, Warp and the kernels load) ends the process
with one line and exit code 130 (SIGTERM: 143), never a traceback; ``wrt.cli.console`` does the rest.
"""

import signal
import sys


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread as Ctrl-C raises ``KeyboardInterrupt``, so that the same
    clean-up runs (a file being written is left as it was, its temporary file removed); exit code
    143 where Ctrl-C's is 130."""


def terminate(signum, frame):
    raise Terminated()


class held_signals:
    """Ctrl-C and SIGTERM held, in the main thread, for the ``with`` block, then delivered: for
    the import of a native extension that cannot take an exception mid-set-up. OpenImageIO's
    nanobind module aborts the process ("Critical nanobind error", SIGABRT) when a signal
    handler's exception reaches it while it registers its enums. Elsewhere a no-op."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __enter__(self):
        self.pending, self.saved = [], {}
        try:
            for signum in self.SIGNALS:
                self.saved[signum] = signal.signal(signum, lambda s, frame: self.pending.append(s))
        except ValueError:  # not the main thread, which alone takes signals
            pass
        return self

    def __exit__(self, *exc) -> None:
        for signum, handler in self.saved.items():
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)
        for signum in self.pending:  # to the handlers restored: an exception, or the default action
            signal.raise_signal(signum)


def main() -> int:
    signal.signal(signal.SIGTERM, terminate)
    try:
        from wrt.cli import console
    except KeyboardInterrupt as e:
        terminated = isinstance(e, Terminated)
        print(f"wrt: {'terminated' if terminated else 'interrupted'}", file=sys.stderr)
        return 143 if terminated else 130
    return console()
