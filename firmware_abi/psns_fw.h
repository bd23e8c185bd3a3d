/*
 * psns_fw.h -- the lockstep firmware interface of psns-hil, version 1 (docs/icd.md section 10).
 *
 * A foreign firmware (a team's C code for the C6747, built for the host) takes the virtual DSP's place behind the
 * DSP's four UARTs and its 1 MHz time base, stepped by the emulator's clock: in fast mode it runs as fast as it
 * answers, bit for bit the same every run. Two transports carry the same four calls:
 *
 *   in-process      the firmware is a shared library exporting the functions below, loaded with ctypes
 *                   (`dsp: {external: {lockstep: {library: PATH}}}`);
 *   out-of-process  the firmware is a program in any language that reads requests on its stdin and writes replies
 *                   on its stdout, framed as in docs/icd.md section 10.3
 *                   (`dsp: {external: {lockstep: {command: [PATH, ARGS...]}}}`).
 *
 * Order of calls: psns_fw_abi_version, psns_fw_init once, then any sequence of psns_fw_rx and psns_fw_step with
 * non-decreasing t_us, then psns_fw_close once. Single-threaded: the emulator never calls two at once.
 *
 * ABI rules: fixed-width integers and IEEE-754 doubles only; the one structure (psns_fw_config) is 64 bytes, every
 * field naturally aligned, no padding, little-endian (all supported hosts); new fields only ever replace the
 * reserved ones or are appended behind a new PSNS_FW_ABI_VERSION.
 */
#ifndef PSNS_FW_H
#define PSNS_FW_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* the version of this interface; psns_fw_abi_version() of a firmware built against it returns it */
#define PSNS_FW_ABI_VERSION 1u

/* the DSP's UARTs: 0 host (commands in, NAV_SOLUTION/STATUS/ACK out), 1 IMU/MAG frames from the FPGA,
 * 2 polarization sensor, 3 GNSS (the FPGA's UART core) -- docs/icd.md sections 4-7 */
#define PSNS_FW_UARTS 4u

/* config.flags bit 0: the gyro words of the IMU frame are incremental angles (2^-21 deg), not rates (2^-14 deg/s) */
#define PSNS_FW_FLAG_GYRO_INCREMENTAL 0x1u

/* return codes of psns_fw_init, psns_fw_rx and psns_fw_step */
#define PSNS_FW_OK 0     /* psns_fw_step: the firmware ran a tick (cycles and outputs are counted) */
#define PSNS_FW_IDLE 1   /* psns_fw_step only: nothing to do (no tick; cycles and tx_len must be 0) */
/* any negative value: the firmware's own fatal error; the emulator stops calling it and reports the code */

/* what the emulator tells the firmware at start: the DSP, the IMU, and the operator's initial values (the ones
 * gyro_nav takes on its command line). 64 bytes, offsets in the comments. */
typedef struct psns_fw_config {
    uint32_t abi_version;   /*  0: PSNS_FW_ABI_VERSION of the emulator */
    uint32_t clock_hz;      /*  4: DSP CPU clock, Hz (C6747: 300 MHz): the cycles reported convert at this rate */
    uint32_t imu_rate_hz;   /*  8: IMU frame rate on UART1, Hz (200) */
    uint32_t flags;         /* 12: PSNS_FW_FLAG_* */
    double lat_deg;         /* 16: initial WGS-84 latitude, deg */
    double lon_deg;         /* 24: initial longitude, deg */
    double height_m;        /* 32: initial ellipsoidal height, m */
    double heading_deg;     /* 40: initial heading, clockwise from true north, deg */
    double pitch_deg;       /* 48: initial pitch, nose up positive, deg */
    double roll_deg;        /* 56: initial roll, right wing down positive, deg */
} psns_fw_config;

typedef char psns_fw_config_is_64_bytes[(sizeof(psns_fw_config) == 64) ? 1 : -1];

/* The interface version the firmware was built against (PSNS_FW_ABI_VERSION). */
uint32_t psns_fw_abi_version(void);

/* Start (or restart) the firmware. Returns PSNS_FW_OK or a negative error. */
int32_t psns_fw_init(const psns_fw_config *config);

/* Bytes that arrived on `uart` (0..3) through its FIFO; the last one arrived at `t_us` (the DSP's 1 MHz time base,
 * microseconds since the scenario's start). The firmware copies them (the buffer is the emulator's). The bytes
 * are hostile input: the firmware validates them. Returns PSNS_FW_OK or a negative error. */
int32_t psns_fw_rx(uint32_t uart, const uint8_t *data, uint32_t n, uint64_t t_us);

/* Run the firmware's main loop once at `t_us` (the instant the DSP is free after an IMU frame arrived on UART1).
 * `tx` holds PSNS_FW_UARTS buffers of `tx_cap` bytes each: the bytes written to UART k go to tx + k * tx_cap and
 * their count to tx_len[k] (<= tx_cap). `*cycles`: the CPU cycles the step spent (the C6747's TSCL/TSCH difference
 * on a board, an estimate on the host); the emulator turns them into time at config.clock_hz -- the outputs leave
 * their UARTs at t_us + cycles / clock_hz, a step longer than one IMU period is a deadline miss.
 * Returns PSNS_FW_OK (a tick ran), PSNS_FW_IDLE (nothing to do) or a negative error. */
int32_t psns_fw_step(uint64_t t_us, uint8_t *tx, uint32_t tx_cap, uint32_t tx_len[PSNS_FW_UARTS], uint64_t *cycles);

/* The run is over: release what psns_fw_init took. */
void psns_fw_close(void);

#ifdef __cplusplus
}
#endif

#endif /* PSNS_FW_H */
