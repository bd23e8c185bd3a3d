"""Split-process runs: the virtual DSP in its own OS process, joined to the virtual FPGA over zenoh.

``psns-hil run --split SCENARIO`` runs the scenario with the same assembly as a single-process run
(:class:`emulator.assembly.session.Emulator`), cut at the FPGA-DSP UARTs:

* the **FPGA process** (this one) holds the world, the sensors, the external ports, the virtual FPGA
  and the recorder. Its ends of UART0-3 are :class:`~emulator.links.zenoh.ZenohLink` s
  (``zenoh://<run>/uartN``, role ``device``) instead of in-process ``mem://`` ends;
* the **DSP process** (``python -m emulator.cli.dsp_process ...``, started by this one) holds the
  firmware on a :class:`~emulator.dsp.host.VirtualDsp` whose UART ends are the ``peer`` side of
  the same keys.

Each end paces what it transmits with its own line model and delivers what it receives without
pacing again (``pace=0``), exactly as the two ends of a ``mem://`` pair do, so the only difference
from a single-process run is the transport latency between the two event loops (about 1 ms on
loopback: median 1.0 ms, p99 2 ms measured loop to loop; zenoh itself takes ~0.13 ms one way,
``docs/reference/wire-formats.md`` section 4). The byte spacing of each chunk (which the DSP's UART FIFO model
uses) travels with it as the zenoh attachment. The run is realtime (the two processes share the wall clock).

Control messages (JSON) on ``psns/<run>/ctl/<kind>``::

    ``ready``   DSP -> FPGA: links and subscribers are up.
    ``start``   FPGA -> DSP: ``{"t0_monotonic", "speed"}``: scenario time 0 on the host's monotonic clock
                (``CLOCK_MONOTONIC`` is one clock for all processes of a host), so both processes
                share one scenario clock.
    ``event``   DSP -> FPGA: a device event (deadline miss, firmware event), written by the recorder.
    ``stop``    FPGA -> DSP: the run is over.
    ``summary`` DSP -> FPGA: the ``dsp`` and ``firmware`` sections of the summary.
    ``error``   DSP -> FPGA: the DSP process failed (message).

The FPGA's captures of UART0-3 are recorded with the DSP end's directions (``in`` = towards the
DSP), so that a split run's capture reads like a single-process one (and replays the same way).

Modules: :mod:`.control` (the control channel and what both sides share), :mod:`.fpga` (the FPGA process:
:class:`SplitFpgaEmulator`, :func:`run_split`), :mod:`.dsp` (the DSP process: :func:`run_dsp_process`; its
command line is :mod:`emulator.cli.dsp_process`).
"""

from .control import READY_TIMEOUT_S, STOP_TIMEOUT_S, SplitControl, SplitError, free_tcp_port
from .dsp import run_dsp_process
from .fpga import RemoteDsp, SplitFpgaEmulator, run_split

__all__ = [
    "READY_TIMEOUT_S",
    "STOP_TIMEOUT_S",
    "RemoteDsp",
    "SplitControl",
    "SplitError",
    "SplitFpgaEmulator",
    "free_tcp_port",
    "run_dsp_process",
    "run_split",
]
