"""Run claims: two sweeps on one results store never compute the same run twice.

A sweep claims the runs it is about to compute (`ResultsStore.claim_runs`, one write transaction) and
skips those another live sweep holds; it waits for those to be recorded once its own are done, and
takes them over if their holder dies. A claim is dropped when its run is recorded, and all of a
sweep's claims when it ends (`ResultsStore.release_claims`, also on an exception or Ctrl-C).

A claim names its holder: the host, the process id and that process's start time (Linux
``/proc/<pid>/stat``; elsewhere none), and a token per sweep, so two sweeps of one process (threads)
are told apart too. Whether a holder is alive:
- on this host: the process exists and started when the claim says (a reused pid is not the holder);
- on another host (a store on a shared folder): it cannot be checked, so a claim younger than
  `FOREIGN_CLAIM_TTL_S` is taken as alive. A sweep killed there holds its runs until then; delete the
  store's ``run_claims`` rows to release them sooner.
A killed sweep (kill -9) leaves its claims; the next sweep finds the holder dead and takes them.
"""

from __future__ import annotations

import dataclasses
import os
import socket
import time
import uuid

#: how long a claim made on another host counts as held (its holder's liveness cannot be checked)
FOREIGN_CLAIM_TTL_S = 24 * 3600.0


def process_start_time(pid: int) -> str:
    """The start time of process ``pid`` in clock ticks since boot (``/proc/<pid>/stat`` field 22),
    '' where there is no /proc or no such process: with the pid it names one process, pid reuse apart."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as stat:
            text = stat.read()
    except OSError:
        return ""
    # the command name (field 2) is in parentheses and may hold spaces: split after its last ')'
    fields = text[text.rfind(")") + 2:].split()
    return fields[19] if len(fields) > 19 else ""


@dataclasses.dataclass(frozen=True)
class ClaimHolder:
    """Who holds a claim: one sweep of one process on one host."""

    token: str
    host: str
    pid: int
    started: str  # `process_start_time` of ``pid`` ('' where unknown)

    @classmethod
    def this_sweep(cls) -> ClaimHolder:
        """A new holder for a sweep starting in this process."""
        pid = os.getpid()
        return cls(token=uuid.uuid4().hex, host=socket.gethostname(), pid=pid, started=process_start_time(pid))

    def is_alive(self, claimed_at: float, now: float | None = None) -> bool:
        """Whether the sweep that made a claim at ``claimed_at`` (epoch seconds) may still be running."""
        now = time.time() if now is None else now
        if self.host != socket.gethostname():
            return now - claimed_at < FOREIGN_CLAIM_TTL_S
        try:
            os.kill(self.pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:  # another user's process: it exists
            pass
        return not self.started or process_start_time(self.pid) in ("", self.started)

    def describe(self) -> str:
        return f"pid {self.pid} on {self.host}"
