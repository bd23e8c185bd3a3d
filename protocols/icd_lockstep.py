"""docs/icd.md section 10: the lockstep firmware interface v1 (issue 40), written by :func:`protocols.icd.generate`.

The contract between the emulator and a foreign firmware that takes the virtual DSP's place in virtual time; its
C declaration is ``firmware_abi/psns_fw.h`` and its emulator side ``emulator/dsp/lockstep.py``.
"""

from __future__ import annotations

#: docs/icd.md section 10 (the calls, the configuration block, the process framing).
LOCKSTEP_TEXT = """\
## 10. Lockstep firmware interface v1 (a foreign firmware in the virtual DSP's place, in virtual time)

The cut between the virtual FPGA and the virtual DSP -- the DSP's four UARTs and its 1 MHz time base -- can be
taken by a foreign firmware **in lockstep** with the emulator's clock: the emulator hands it the bytes each UART
received, asks it to run one step when an IMU frame has arrived, and waits for the answer: the bytes it wrote per
UART and the CPU cycles it says the step spent. Unlike the pty cut (`dsp.external.uarts`, docs/runtime.md "DSP
out") this is not a byte link: it carries time, steps and cycles, so a run in fast mode is as fast as the firmware
answers and bit for bit the same every run. The C declaration is `firmware_abi/psns_fw.h` (the contract's one
source for C; this section is its wire description). Interface version: **1** (`PSNS_FW_ABI_VERSION`).

### 10.1 Calls and their order

| call | arguments | result | when |
|---|---|---|---|
| `psns_fw_abi_version()` | | u32: the version the firmware was built against | once, first; must equal 1 |
| `psns_fw_init(config)` | `psns_fw_config` (10.2) | i32: 0 ok, < 0 fatal | once |
| `psns_fw_rx(uart, data, n, t_us)` | u32 UART 0..3, n bytes, u64 us | i32: 0 ok, < 0 fatal | every chunk a \
UART's FIFO passes on, in arrival order |
| `psns_fw_step(t_us, tx, tx_cap, tx_len[4], *cycles)` | u64 us; 4 x `tx_cap` output bytes | i32: 0 ran a tick, \
1 idle, < 0 fatal | once after each IMU-frame chunk on UART1, at the instant the DSP is free |
| `psns_fw_close()` | | | once, at the end |

`t_us` is the DSP's 1 MHz time base: microseconds since the scenario's start, non-decreasing over the calls.
UART numbers: 0 host (docs/icd.md section 7, both directions), 1 IMU and MAG frames (section 4), 2 polarization
sensor (section 6), 3 GNSS (section 5). The firmware's outputs: the bytes it wrote to UART k during the step, at
most `tx_cap` (the emulator passes 65536) per UART.

**Time and cycles.** A step that starts at `t_us` and reports `cycles` ends at `t_us + cycles / clock_hz`; its
outputs leave their UARTs at that instant, through the DSP's TX path and the UART's line model, exactly as the
built-in firmware's do (emulator/dsp/host.py): a step that ends later than one IMU period after its frame
arrived is a counted **deadline miss**, a step longer than `dsp.watchdog.overrun_multiple` periods trips the
watchdog (flag only: a foreign firmware is not restarted), and the summary's cycle table (`dsp.tasks`, task
`lockstep_step`) shows calls, min/avg/max cycles and the share of the tick budget. An idle step (return 1) must
report 0 cycles and no output; it is not a tick.

**Hostile in both directions.** The UART bytes the firmware gets are the line's, errors and all; what it returns
is checked by the emulator: a return code other than 0/1, a `tx_len` above `tx_cap`, more than 60 s of cycles in
one step, or (out-of-process) a malformed reply, an exit, or no reply within `step_timeout_s` wall-clock seconds
stop the firmware: the reason is counted and reported (`summary.json` section `lockstep`, event
`lockstep_failed`), the DSP stays silent for the rest of the run, the run directory is written and `psns-hil run`
exits 1 naming the reason. Bytes it writes are decoded at the host port like the virtual DSP's (garbage, CRC
errors counted); a flood overflows the UART's line and TX ring and is counted there.

### 10.2 `psns_fw_config` (64 bytes, little-endian, no padding)

| offset | size | type | field | unit | meaning |
|---|---|---|---|---|---|
| 0 | 4 | u32 LE | abi_version | | 1 |
| 4 | 4 | u32 LE | clock_hz | Hz | DSP CPU clock (`dsp.clock_hz`, 300 MHz) |
| 8 | 4 | u32 LE | imu_rate_hz | Hz | IMU frame rate on UART1 |
| 12 | 4 | u32 LE | flags | | bit 0: gyro words are incremental angles (2^-21 deg) rather than rates (2^-14 \
deg/s) |
| 16 | 8 | f64 LE | lat_deg | deg | initial WGS-84 latitude (scenario `origin`) |
| 24 | 8 | f64 LE | lon_deg | deg | initial longitude |
| 32 | 8 | f64 LE | height_m | m | initial ellipsoidal height |
| 40 | 8 | f64 LE | heading_deg | deg | initial heading, clockwise from true north (scenario `attitude`) |
| 48 | 8 | f64 LE | pitch_deg | deg | initial pitch, nose up positive |
| 56 | 8 | f64 LE | roll_deg | deg | initial roll, right wing down positive |

### 10.3 Out-of-process framing (stdin / stdout of the firmware process)

The same calls as messages: the emulator writes requests on the process's stdin and reads replies on its stdout
(its stderr goes to `lockstep_stderr.log` in the run directory; a firmware must print nothing else on stdout).
Every message starts with an 8-byte header:

| offset | size | type | field | meaning |
|---|---|---|---|---|
| 0 | 1 | u8 | type | request: `I` 0x49 init, `R` 0x52 rx, `S` 0x53 step, `Q` 0x51 quit; reply: the same letter \
in lower case |
| 1 | 1 | u8 = 0x01 | version | interface version |
| 2 | 2 | u16 LE = 0 | reserved | |
| 4 | 4 | u32 LE | length | payload bytes that follow (<= 1048576 in a reply) |

| message | payload | reply |
|---|---|---|
| `I` init | the 64-byte config (10.2) | `i`: u32 abi_version, i32 status (8 bytes) |
| `R` rx | u32 uart, u32 reserved 0, u64 t_us, the n bytes (16 + n) | none |
| `S` step | u64 t_us, u32 tx_cap, u32 reserved 0 (16) | `s`: i32 status, u32 reserved 0, u64 cycles, u32 \
tx_len[4], then the tx_len[0] + .. + tx_len[3] bytes, UART 0 first (32 + sum) |
| `Q` quit | none | none: the process exits (status 0) |

The emulator may write several `R` messages and one `S` in a single write; it waits for the `s` reply (no more
than `step_timeout_s` of wall-clock time, default 10 s) before its clock goes on. Requests and replies are
little-endian. A reply of the wrong type, version, length or size, an end of file on stdout, or a timeout is a
failure (10.1).
"""
