"""How a command stops when asked: Ctrl-C (SIGINT) or SIGTERM ends it with one line saying what was
kept, and the shell's exit code for the signal (130, 143), never a traceback.

Every console command runs its work through ``run_stoppable``. The work cleans up as any exception
passes (staging folders, atomic writes); this module owns the rest: the handlers, recognising the
stop however Dr.Jit or torch wrapped it, the message and the exit code. A handler's exception can be
lost (raised while the interpreter runs a finalizer, it is printed as ignored and the run goes on:
seen about once in eight Ctrl-Cs during refinement), so the long loops call ``raise_if_requested``
at each step.
"""

from __future__ import annotations

import contextlib
import sys
import threading
from collections.abc import Callable

INTERRUPTED_CODE = 130  # 128 + SIGINT, what a shell reports for a command ended by Ctrl-C
TERMINATED_CODE = 143  # 128 + SIGTERM


class Terminated(Exception):
    """Raised in the main thread by SIGTERM, so that a run cleans up as on Ctrl-C."""


# The stop a signal asked for, set by the handlers below. Dr.Jit and torch may wrap the exception a
# handler raises (a signal landing inside the fast layer's ``dr.custom`` operation reaches Python as a
# RuntimeError), so whatever error follows a signal ends the run as the stop the user asked for.
_requested_stop: type[BaseException] | None = None


def on_sigterm(signum, frame):
    global _requested_stop
    _requested_stop = Terminated
    raise Terminated


def on_sigint(signum, frame):
    global _requested_stop
    _requested_stop = KeyboardInterrupt
    raise KeyboardInterrupt


_thread_checks = threading.local()


def raise_if_requested() -> None:
    """Raise the stop a signal asked for, if one did: a loop's safe point, should the handler's own
    exception have been lost. Does nothing outside ``run_stoppable`` (library calls) unless the calling
    thread is ``checking``: then its check runs too."""
    if _requested_stop is not None:
        raise _requested_stop
    check = getattr(_thread_checks, "check", None)
    if check is not None:
        check()


@contextlib.contextmanager
def checking(check: Callable[[], None]):
    """Within it, ``raise_if_requested`` in this thread also calls ``check()`` at the work's safe points,
    which raises when the caller wants the work to end: the live preview ends a look's fit there when
    the page picks another style (and shows a camera move meanwhile)."""
    previous = getattr(_thread_checks, "check", None)
    _thread_checks.check = check
    try:
        yield
    finally:
        _thread_checks.check = previous


def requested_stop(error: BaseException) -> type[BaseException] | None:
    """The stop (``KeyboardInterrupt`` or ``Terminated``) behind ``error``: a signal received during the
    run, or one found among the exceptions that caused ``error``."""
    if _requested_stop is not None:
        return _requested_stop
    seen = set()
    while error is not None and id(error) not in seen:
        if isinstance(error, (KeyboardInterrupt, Terminated)):
            return type(error)
        seen.add(id(error))
        error = error.__cause__ or error.__context__
    return None


def stopped(message: str, code: int, in_process: bool) -> int:
    """Say why a run stopped; return ``code`` to an in-process caller (``main(argv)``), and end the
    command's process with it at once. The signal may also have reached Mitsuba's or torch's threads,
    and the interpreter's shutdown could then end the process by the signal instead of ``code``
    (measured: about one Ctrl-C in four); the work has cleaned up already."""
    import os

    print(message, file=sys.stderr)
    if in_process:
        return code
    sys.stderr.flush()
    sys.stdout.flush()
    os._exit(code)


def run_stoppable(work: Callable[[], int], kept: str, in_process: bool) -> int:
    """``work()``'s exit code; on Ctrl-C or SIGTERM, ``"interrupted: <kept>"`` or ``"terminated: <kept>"``
    on stderr and 130 or 143 (``kept``: what the user has after the stop, and how to go on). Other
    errors pass through to the command's own handlers. Handlers are installed in the main thread only,
    and Ctrl-C's only where it is not ignored (a command started in the background)."""
    import signal
    import threading

    global _requested_stop
    previous = {}
    if threading.current_thread() is threading.main_thread():
        previous[signal.SIGTERM] = signal.signal(signal.SIGTERM, on_sigterm)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            previous[signal.SIGINT] = signal.signal(signal.SIGINT, on_sigint)
    try:
        try:
            code = work()
            raise_if_requested()  # a stop lost after the last safe point
            return code
        except Exception as error:
            stop = requested_stop(error)
            if stop is None:
                raise
            raise stop from None
    except KeyboardInterrupt:
        return stopped(f"interrupted: {kept}", INTERRUPTED_CODE, in_process)
    except Terminated:
        return stopped(f"terminated: {kept}", TERMINATED_CODE, in_process)
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
        _requested_stop = None  # library calls after an in-process run are not stopped by its signal
