/*
 * psns_nav: the example foreign firmware of psns-hil, a free-inertial strapdown navigator in C behind the lockstep
 * firmware interface (firmware_abi/psns_fw.h, docs/icd.md section 10). One source set, three builds
 * (Makefile): the lockstep shared library (libpsns_nav.so, in-process), the lockstep process (psns_nav_lockstep,
 * out-of-process, lockstep_proc.c) and the pty program (psns_nav_pty, pty_main.c: the DSP out over ptys in
 * realtime, docs/runtime.md "DSP out").
 *
 * It reads the FPGA's IMU frames on UART1 (docs/icd.md section 4.1: msg_type 0x01, 40 bytes; MAG frames, type
 * 0x02, are skipped) and writes one NAV_SOLUTION (section 7, msg_id 0x01, 102-byte payload) per IMU frame on UART0.
 *
 * Navigation (Titterton & Weston, Strapdown Inertial Navigation Technology, 2nd ed., chapter 3; Savage,
 * Strapdown Analytics, 2nd ed., chapter 7), in the navigation frame n = ENU, body b = x right, y forward, z up:
 *   attitude  q_b^n(k) = q(-w_in^n T) (x) q_b^n(k-1) (x) q(dth_k)          (T&W eq. 3.49, body then nav update)
 *   velocity  v(k) = v(k-1) + C_b^n(k-1) (dv_k + dth_k x dv_k / 2) + (g^n - (2 w_ie^n + w_en^n) x v) T   (eq. 3.73)
 *   position  lat += v_N T / (R_M + h), lon += v_E T / ((R_N + h) cos lat), h += v_U T (mean velocity)  (eq. 3.79)
 * with w_ie^n = W (0, cos L, sin L), w_en^n = (-v_N / (R_M + h), v_E / (R_N + h), v_E tan L / (R_N + h)),
 * g^n = (0, 0, -gamma(L, h)) the WGS-84 normal gravity (NIMA TR8350.2 eq. 4-1 with the free-air series 4-3),
 * dth_k the gyro's mean rate (words x 2^-14 deg/s) times T or its incremental angle (x 2^-21 deg), dv_k the
 * accelerometers' mean specific force (ADC code x 4.096 V / 2^23 / (0.090, 0.108, 0.108) V/g x 9.80665 m/s^2)
 * times T, T the interval between the FPGA's trigger stamps (1 MHz counter). No alignment, no bias estimate, no
 * aiding: the initial attitude and position are the operator's (psns_fw_config), so the errors grow from the
 * gyro and accelerometer biases alone (tests/emulator/dsp/test_lockstep.py derives the bound).
 *
 * Cycles: an estimate of what the C6747 would spend, counted from the work done (never from the host's clock, so
 * that a run is deterministic): PSNS_NAV_CYC_* below, per byte decoded, per strapdown update, per frame encoded.
 *
 * Input is hostile: the decoder resynchronises at header + 1 after a bad sync, length or CRC (CRC-16/CCITT-FALSE
 * over msg_type..last payload byte) and counts what it skipped (psns_nav_counters).
 */
#include "psns_nav.h"

#include <math.h>
#include <string.h>

#define PI 3.14159265358979323846
#define DEG (PI / 180.0)
#define IMU_SYNC0 0x55
#define IMU_SYNC1 0xAA
#define IMU_TYPE 0x01
#define MAG_TYPE 0x02
#define IMU_LEN 40
#define HOST_SYNC0 0xA5
#define HOST_SYNC1 0x5A
#define NAV_ID 0x01
#define NAV_PAYLOAD 102
#define NAV_FRAME (7 + NAV_PAYLOAD)
#define MODE_NAVIGATING 0x0002
#define GYRO_RATE_LSB_DPS (1.0 / 16384.0)     /* 2^-14 deg/s */
#define GYRO_ANGLE_LSB_DEG (1.0 / 2097152.0)  /* 2^-21 deg */
#define ADC_VOLTS_PER_LSB (4.096 / 8388608.0) /* 4.096 V / 2^23 */
#define G_STD 9.80665                         /* m/s^2 per g (the accelerometers' scale, docs/icd.md 4) */
#define RX_RING 8192

/* WGS-84 (NIMA TR8350.2 Tables 3.1-3.4) */
#define WGS84_A 6378137.0
#define WGS84_F (1.0 / 298.257223563)
#define WGS84_E2 6.69437999014e-3
#define WGS84_OMEGA 7.292115e-5
#define GAMMA_E 9.7803253359
#define SOMIGLIANA_K 0.00193185265241
#define GEOD_M 0.00344978650684

/* cycle estimate of the C674x (docs/icd.md section 10.1): per byte through the frame decoder and CRC, per
 * strapdown update in double precision (about 400 DP flops at ~6 cycles with the sin/cos/sqrt calls), per
 * NAV_SOLUTION encoded (fields, CRC), and the fixed cost of a step (the main loop, the UART driver) */
#define PSNS_NAV_CYC_PER_BYTE 14u
#define PSNS_NAV_CYC_STRAPDOWN 3200u
#define PSNS_NAV_CYC_ENCODE 1900u
#define PSNS_NAV_CYC_STEP 600u

static const double VOLTS_PER_G[3] = {0.090, 2.7 / 25.0, 2.7 / 25.0};

static struct state {
    psns_fw_config cfg;
    int ready;
    uint8_t ring[RX_RING];
    uint32_t have;
    double q[4];     /* q_b^n, scalar first */
    double v[3];     /* ENU, m/s */
    double lat, lon; /* rad */
    double h;        /* m */
    int started;
    uint32_t t_prev_us;
    uint32_t seq;
    psns_nav_counters c;
} S;

/* CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no xor (check 0x29B1) */
static uint16_t crc16(const uint8_t *p, size_t n) {
    uint16_t c = 0xFFFF;
    while (n--) {
        c ^= (uint16_t)(*p++) << 8;
        for (int i = 0; i < 8; i++) c = (c & 0x8000) ? (uint16_t)((c << 1) ^ 0x1021) : (uint16_t)(c << 1);
    }
    return c;
}

static uint32_t u32le(const uint8_t *p) {
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}
static int32_t s24le(const uint8_t *p) {
    int32_t v = (int32_t)((uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16));
    return (v & 0x800000) ? v - 0x1000000 : v;
}
static void put_u16(uint8_t *p, uint16_t v) { p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); }
static void put_u32(uint8_t *p, uint32_t v) { for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i)); }
static void put_f64(uint8_t *p, double v) {
    uint64_t u; memcpy(&u, &v, 8);
    for (int i = 0; i < 8; i++) p[i] = (uint8_t)(u >> (8 * i));
}
static void put_f32(uint8_t *p, float v) { uint32_t u; memcpy(&u, &v, 4); put_u32(p, u); }

/* quaternions, scalar first, Hamilton product */
static void qmul(const double a[4], const double b[4], double r[4]) {
    double t[4] = {a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
                   a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
                   a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
                   a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]};
    memcpy(r, t, sizeof t);
}
static void qaxis(int axis, double angle, double q[4]) {
    q[0] = cos(angle / 2); q[1] = q[2] = q[3] = 0.0; q[1 + axis] = sin(angle / 2);
}
static void qrotvec(const double v[3], double q[4]) { /* exp of a rotation vector, rad */
    double a = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    double s = a > 1e-12 ? sin(a / 2) / a : 0.5 - a * a / 48.0;
    q[0] = cos(a / 2); q[1] = s * v[0]; q[2] = s * v[1]; q[3] = s * v[2];
}
static void q2dcm(const double q[4], double C[3][3]) { /* C_b^n */
    double w = q[0], x = q[1], y = q[2], z = q[3];
    C[0][0] = w * w + x * x - y * y - z * z; C[0][1] = 2 * (x * y - w * z); C[0][2] = 2 * (x * z + w * y);
    C[1][0] = 2 * (x * y + w * z); C[1][1] = w * w - x * x + y * y - z * z; C[1][2] = 2 * (y * z - w * x);
    C[2][0] = 2 * (x * z - w * y); C[2][1] = 2 * (y * z + w * x); C[2][2] = w * w - x * x - y * y + z * z;
}
static void cross(const double a[3], const double b[3], double r[3]) {
    double t[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    memcpy(r, t, sizeof t);
}

/* WGS-84 normal gravity, m/s^2: Somigliana (TR8350.2 eq. 4-1), free-air series (eq. 4-3) */
static double normal_gravity(double lat, double h) {
    double s2 = sin(lat) * sin(lat);
    double g0 = GAMMA_E * (1.0 + SOMIGLIANA_K * s2) / sqrt(1.0 - WGS84_E2 * s2);
    return g0 * (1.0 - 2.0 / WGS84_A * (1.0 + WGS84_F + GEOD_M - 2.0 * WGS84_F * s2) * h
                 + 3.0 * h * h / (WGS84_A * WGS84_A));
}

static void mechanize(const double dth[3], const double dv[3], double T) {
    double sl = sin(S.lat), cl = cos(S.lat), d = 1.0 - WGS84_E2 * sl * sl;
    double rn = WGS84_A / sqrt(d), rm = WGS84_A * (1.0 - WGS84_E2) / (d * sqrt(d));
    double wie[3] = {0.0, WGS84_OMEGA * cl, WGS84_OMEGA * sl};
    double wen[3] = {-S.v[1] / (rm + S.h), S.v[0] / (rn + S.h), S.v[0] * sl / cl / (rn + S.h)};
    double C[3][3], sc[3], dvb[3], cor[3], w2[3];
    /* velocity with the attitude at the start of the interval and the rotation correction */
    q2dcm(S.q, C);
    cross(dth, dv, sc);
    for (int i = 0; i < 3; i++) dvb[i] = dv[i] + 0.5 * sc[i];
    for (int i = 0; i < 3; i++) w2[i] = 2.0 * wie[i] + wen[i];
    cross(w2, S.v, cor);
    double g = normal_gravity(S.lat, S.h);
    double v_old[3] = {S.v[0], S.v[1], S.v[2]};
    for (int i = 0; i < 3; i++)
        S.v[i] += C[i][0] * dvb[0] + C[i][1] * dvb[1] + C[i][2] * dvb[2] - cor[i] * T;
    S.v[2] -= g * T;
    /* attitude: body rotation, then the navigation frame's rotation over T */
    double qb[4], qn[4], win[3];
    qrotvec(dth, qb);
    qmul(S.q, qb, S.q);
    for (int i = 0; i < 3; i++) win[i] = -(wie[i] + wen[i]) * T;
    qrotvec(win, qn);
    qmul(qn, S.q, S.q);
    double nq = sqrt(S.q[0] * S.q[0] + S.q[1] * S.q[1] + S.q[2] * S.q[2] + S.q[3] * S.q[3]);
    for (int i = 0; i < 4; i++) S.q[i] /= nq;
    /* position with the mean velocity over the interval */
    double ve = 0.5 * (v_old[0] + S.v[0]), vn = 0.5 * (v_old[1] + S.v[1]), vu = 0.5 * (v_old[2] + S.v[2]);
    S.lat += vn * T / (rm + S.h);
    S.lon += ve * T / ((rn + S.h) * cl);
    S.h += vu * T;
}

/* PSINS m2att on C_b^n: pitch = asin(C32), roll = atan2(-C31, C33), yaw = atan2(-C12, C22) */
static void euler(const double q[4], double *roll, double *pitch, double *heading) {
    double C[3][3];
    q2dcm(q, C);
    double c32 = C[2][1] > 1 ? 1 : (C[2][1] < -1 ? -1 : C[2][1]);
    *pitch = asin(c32);
    *roll = atan2(-C[2][0], C[2][2]);
    double yaw = atan2(-C[0][1], C[1][1]);
    *heading = fmod(-yaw / DEG + 360.0, 360.0);
}

static uint32_t encode_nav(uint32_t t_us, uint8_t *out) {
    double roll, pitch, heading;
    euler(S.q, &roll, &pitch, &heading);
    uint8_t *pl = out + 5;
    memset(out, 0, NAV_FRAME);
    out[0] = HOST_SYNC0; out[1] = HOST_SYNC1; out[2] = NAV_ID; put_u16(out + 3, NAV_PAYLOAD);
    put_u32(pl + 0, S.seq++);
    put_f64(pl + 4, t_us * 1e-6);
    put_f64(pl + 12, S.lat / DEG); put_f64(pl + 20, S.lon / DEG); put_f32(pl + 28, (float)S.h);
    for (int i = 0; i < 3; i++) put_f32(pl + 32 + 4 * i, (float)S.v[i]);
    put_f32(pl + 44, (float)(roll / DEG)); put_f32(pl + 48, (float)(pitch / DEG)); put_f32(pl + 52, (float)heading);
    /* sigma (56..91) 0: no filter; gnss/psns status 0; cpu_load, deadline_misses 0 (not observed from inside) */
    put_u16(pl + 92, MODE_NAVIGATING);
    put_u16(out + 5 + NAV_PAYLOAD, crc16(out + 2, 3 + NAV_PAYLOAD));
    return NAV_FRAME;
}

uint32_t psns_fw_abi_version(void) { return PSNS_FW_ABI_VERSION; }

int32_t psns_fw_init(const psns_fw_config *config) {
    if (config == NULL || config->abi_version != PSNS_FW_ABI_VERSION) return -1;
    memset(&S, 0, sizeof S);
    S.cfg = *config;
    /* q_b^n = q_z(yaw) (x) q_x(pitch) (x) q_y(roll), yaw = -heading: C_b^n = R_z(yaw) R_x(pitch) R_y(roll) */
    double qa[4], qb[4];
    qaxis(2, -config->heading_deg * DEG, qa); qaxis(0, config->pitch_deg * DEG, qb); qmul(qa, qb, S.q);
    qaxis(1, config->roll_deg * DEG, qb); qmul(S.q, qb, S.q);
    S.lat = config->lat_deg * DEG;
    S.lon = config->lon_deg * DEG;
    S.h = config->height_m;
    S.ready = 1;
    return PSNS_FW_OK;
}

int32_t psns_fw_rx(uint32_t uart, const uint8_t *data, uint32_t n, uint64_t t_us) {
    (void)t_us;
    if (!S.ready) return -1;
    if (uart != 1) { S.c.other_uart_bytes += n; return PSNS_FW_OK; } /* host commands, PSNS, GNSS: not used */
    uint32_t room = RX_RING - S.have;
    if (n > room) { S.c.ring_overflow_bytes += n - room; n = room; }
    memcpy(S.ring + S.have, data, n);
    S.have += n;
    return PSNS_FW_OK;
}

int32_t psns_fw_step(uint64_t t_us, uint8_t *tx, uint32_t tx_cap, uint32_t tx_len[PSNS_FW_UARTS], uint64_t *cycles) {
    (void)t_us;
    for (uint32_t k = 0; k < PSNS_FW_UARTS; k++) tx_len[k] = 0;
    *cycles = 0;
    if (!S.ready) return -1;
    uint64_t cyc = 0;
    uint32_t i = 0, frames = 0;
    while (S.have - i >= 4) {
        const uint8_t *f = S.ring + i;
        if (f[0] != IMU_SYNC0 || f[1] != IMU_SYNC1) { S.c.garbage_bytes++; i++; continue; }
        uint32_t len = 4u + f[3] + 2u;
        if (len > 64) { S.c.length_errors++; i++; continue; }
        if (S.have - i < len) break;
        if (crc16(f + 2, len - 4) != (uint16_t)(f[len - 2] | (f[len - 1] << 8))) { S.c.crc_errors++; i++; continue; }
        i += len;
        cyc += (uint64_t)len * PSNS_NAV_CYC_PER_BYTE;
        if (f[2] == MAG_TYPE) { S.c.mag_frames++; continue; }
        if (f[2] != IMU_TYPE || len != IMU_LEN) { S.c.other_frames++; continue; }
        S.c.imu_frames++;
        frames++;
        uint32_t t_trig = u32le(f + 6);
        if (S.started) {
            double T = (double)(uint32_t)(t_trig - S.t_prev_us) * 1e-6; /* the counter wraps at 2^32 us */
            double dth[3], dv[3];
            for (int k = 0; k < 3; k++) {
                int32_t w = s24le(f + 15 + 3 * k);
                dth[k] = (S.cfg.flags & PSNS_FW_FLAG_GYRO_INCREMENTAL) ? w * GYRO_ANGLE_LSB_DEG * DEG
                                                                      : w * GYRO_RATE_LSB_DPS * DEG * T;
                dv[k] = s24le(f + 28 + 3 * k) * ADC_VOLTS_PER_LSB / VOLTS_PER_G[k] * G_STD * T;
            }
            if (T > 0.0 && T < 1.0) mechanize(dth, dv, T);
            else S.c.time_jumps++;
            cyc += PSNS_NAV_CYC_STRAPDOWN;
        }
        S.started = 1;
        S.t_prev_us = t_trig;
        if (tx_len[0] + NAV_FRAME <= tx_cap) {
            tx_len[0] += encode_nav(t_trig, tx + tx_len[0]);
            S.c.nav_frames_out++;
        } else {
            S.c.tx_overflow_frames++;
        }
        cyc += PSNS_NAV_CYC_ENCODE + NAV_FRAME * PSNS_NAV_CYC_PER_BYTE;
    }
    memmove(S.ring, S.ring + i, S.have - i);
    S.have -= i;
    if (!frames && !tx_len[0]) return PSNS_FW_IDLE;
    *cycles = cyc + PSNS_NAV_CYC_STEP;
    return PSNS_FW_OK;
}

void psns_fw_close(void) { S.ready = 0; }

const psns_nav_counters *psns_nav_get_counters(void) { return &S.c; }
