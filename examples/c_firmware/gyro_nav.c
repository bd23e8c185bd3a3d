/*
 * gyro_nav: a foreign firmware for the psns-hil emulator's "DSP out" mode (docs/runtime.md, section DSP out).
 *
 * It stands where the C6747 firmware would: it reads the FPGA's frames on its UART1 (IMU frame, msg_type 0x01,
 * 40 bytes; MAG frames, msg_type 0x02, are skipped), integrates the gyro's mean angular rate into an attitude
 * quaternion, and writes one NAV_SOLUTION frame (host frame msg_id 0x01, 102-byte payload) per IMU frame on its
 * UART0. Wire layouts: docs/icd.md sections 4.1 (IMU frame) and 7 (host frame, NAV_SOLUTION).
 *
 * Algorithm (gyro only, on purpose the simplest navigation there is):
 *   q_b^n(t_0) from the attitude given on the command line (heading clockwise from north, pitch, roll, deg);
 *   q_b^n(t_k) = q_b^n(t_{k-1}) (x) exp(w_k (t_k - t_{k-1}) / 2),   w_k the gyro words x 2^-14 deg/s
 *   (the STIM's mean rate over the trigger interval), t_k the FPGA trigger time stamp (1 MHz counter);
 *   no Earth-rate or transport-rate correction, no bias estimate: the attitude drifts by the gyro's bias
 *   and by the Earth's rotation as seen in the body. Position is held at the command line's value, velocity 0.
 * Frames: body x right, y forward, z up; navigation ENU; C_n^b = R_Y(roll) R_X(pitch) R_Z(yaw), yaw = -heading
 * (docs/architecture.md, Conventions).
 *
 * Input is hostile: the decoder resynchronises at header + 1 after a bad sync, length or CRC (CRC-16/CCITT-FALSE
 * over msg_type..last payload byte) and counts what it skipped; the counters go to stderr at exit.
 *
 * Usage: gyro_nav --imu PATH --host PATH --attitude HEADING,PITCH,ROLL --position LAT,LON,HEIGHT
 *   PATH are serial devices or the emulator's pty symlinks (<run_dir>/ports/NAME). It runs until its UART1
 *   hangs up (the emulator closed the port) or it gets SIGTERM / SIGINT.
 */
#define _DEFAULT_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>

#define DEG (M_PI / 180.0)
#define IMU_SYNC0 0x55
#define IMU_SYNC1 0xAA
#define IMU_TYPE 0x01
#define IMU_LEN 40
#define HOST_SYNC0 0xA5
#define HOST_SYNC1 0x5A
#define NAV_ID 0x01
#define NAV_PAYLOAD 102
#define MODE_NAVIGATING 0x0002
#define GYRO_LSB_DPS (1.0 / 16384.0) /* 2^-14 deg/s */

static volatile sig_atomic_t stop_requested = 0;
static void on_signal(int sig) { (void)sig; stop_requested = 1; }

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
static void put_f64(uint8_t *p, double v) { uint64_t u; memcpy(&u, &v, 8); for (int i = 0; i < 8; i++) p[i] = (uint8_t)(u >> (8 * i)); }
static void put_f32(uint8_t *p, float v) { uint32_t u; memcpy(&u, &v, 4); put_u32(p, u); }

/* quaternions, scalar first, Hamilton */
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
/* PSINS m2att on C_b^n: pitch = asin(C32), roll = atan2(-C31, C33), yaw = atan2(-C12, C22) */
static void q2att(const double q[4], double *pitch, double *roll, double *yaw) {
    double w = q[0], x = q[1], y = q[2], z = q[3];
    double c12 = 2 * (x * y - w * z), c22 = w * w - x * x + y * y - z * z;
    double c31 = 2 * (x * z - w * y), c32 = 2 * (y * z + w * x), c33 = w * w - x * x - y * y + z * z;
    *pitch = asin(c32 > 1 ? 1 : (c32 < -1 ? -1 : c32));
    *roll = atan2(-c31, c33);
    *yaw = atan2(-c12, c22);
}

static int open_port(const char *path, int flags) {
    int fd = open(path, flags | O_NOCTTY);
    if (fd < 0) { fprintf(stderr, "gyro_nav: cannot open %s: %s\n", path, strerror(errno)); exit(2); }
    struct termios t;
    if (tcgetattr(fd, &t) == 0) { /* a real serial port: raw 8N1 at 460800 (a pty ignores the speed) */
        cfmakeraw(&t);
        cfsetispeed(&t, B460800); cfsetospeed(&t, B460800);
        t.c_cflag |= CLOCAL | CREAD;
        tcsetattr(fd, TCSANOW, &t);
    }
    return fd;
}

struct counters { unsigned long frames, mag_frames, other_frames, crc_errors, length_errors, garbage, nav_out, write_errors; };

int main(int argc, char **argv) {
    const char *imu_path = NULL, *host_path = NULL;
    double hdg = 0, pit = 0, rol = 0, lat = 0, lon = 0, height = 0;
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!strcmp(argv[i], "--imu")) imu_path = argv[i + 1];
        else if (!strcmp(argv[i], "--host")) host_path = argv[i + 1];
        else if (!strcmp(argv[i], "--attitude")) { if (sscanf(argv[i + 1], "%lf,%lf,%lf", &hdg, &pit, &rol) != 3) goto usage; }
        else if (!strcmp(argv[i], "--position")) { if (sscanf(argv[i + 1], "%lf,%lf,%lf", &lat, &lon, &height) != 3) goto usage; }
        else goto usage;
    }
    if (!imu_path || !host_path) goto usage;
    signal(SIGTERM, on_signal); signal(SIGINT, on_signal); signal(SIGPIPE, SIG_IGN);
    int in_fd = open_port(imu_path, O_RDONLY | O_NONBLOCK);
    int out_fd = strcmp(imu_path, host_path) ? open_port(host_path, O_WRONLY) : in_fd;

    /* q_b^n = q_z(yaw) (x) q_x(pitch) (x) q_y(roll): C_b^n = R_z(yaw) R_x(pitch) R_y(roll) */
    double q[4], qa[4], qb[4];
    qaxis(2, -hdg * DEG, qa); qaxis(0, pit * DEG, qb); qmul(qa, qb, q);
    qaxis(1, rol * DEG, qb); qmul(q, qb, q);

    struct counters c = {0};
    uint8_t buf[4096];
    size_t have = 0;
    int started = 0;
    uint32_t t_prev_us = 0;
    uint32_t seq = 0;
    while (!stop_requested) {
        struct pollfd p = {in_fd, POLLIN, 0};
        int r = poll(&p, 1, 200);
        if (r < 0) { if (errno == EINTR) continue; break; }
        if (r == 0) continue;
        if (p.revents & POLLIN) {
            ssize_t n = read(in_fd, buf + have, sizeof buf - have);
            if (n < 0) { if (errno == EAGAIN || errno == EINTR) continue; break; }
            if (n == 0) break;
            have += (size_t)n;
        } else if (p.revents & (POLLHUP | POLLERR)) {
            break; /* the emulator closed the port: the run is over */
        }
        size_t i = 0;
        while (have - i >= 4) {
            if (buf[i] != IMU_SYNC0 || buf[i + 1] != IMU_SYNC1) { c.garbage++; i++; continue; }
            size_t len = 4 + (size_t)buf[i + 3] + 2;
            if (len > 64) { c.length_errors++; i++; continue; }
            if (have - i < len) break;
            const uint8_t *f = buf + i;
            if (crc16(f + 2, len - 4) != (uint16_t)(f[len - 2] | (f[len - 1] << 8))) { c.crc_errors++; i++; continue; }
            i += len;
            if (f[2] == 0x02) { c.mag_frames++; continue; }
            if (f[2] != IMU_TYPE || len != IMU_LEN) { c.other_frames++; continue; }
            c.frames++;
            uint32_t t_us = u32le(f + 6);
            if (started) {
                double dt = (double)(uint32_t)(t_us - t_prev_us) * 1e-6; /* the counter wraps at 2^32 us */
                double w[3], dq[4];
                for (int k = 0; k < 3; k++) w[k] = s24le(f + 15 + 3 * k) * GYRO_LSB_DPS * DEG * dt;
                qrotvec(w, dq);
                qmul(q, dq, q);
                double nq = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
                for (int k = 0; k < 4; k++) q[k] /= nq;
            }
            started = 1;
            t_prev_us = t_us;
            double pitch, roll, yaw;
            q2att(q, &pitch, &roll, &yaw);
            double heading = fmod(-yaw / DEG + 360.0, 360.0);
            uint8_t out[7 + NAV_PAYLOAD];
            uint8_t *pl = out + 5;
            memset(out, 0, sizeof out);
            out[0] = HOST_SYNC0; out[1] = HOST_SYNC1; out[2] = NAV_ID; put_u16(out + 3, NAV_PAYLOAD);
            put_u32(pl + 0, seq++);
            put_f64(pl + 4, t_us * 1e-6);
            put_f64(pl + 12, lat); put_f64(pl + 20, lon); put_f32(pl + 28, (float)height);
            /* velocity 0 (bytes 32..43), sigma 0 (56..91) */
            put_f32(pl + 44, (float)(roll / DEG)); put_f32(pl + 48, (float)(pitch / DEG)); put_f32(pl + 52, (float)heading);
            put_u16(pl + 92, MODE_NAVIGATING);
            put_u16(out + 5 + NAV_PAYLOAD, crc16(out + 2, 3 + NAV_PAYLOAD));
            size_t off = 0;
            while (off < sizeof out) {
                ssize_t w = write(out_fd, out + off, sizeof out - off);
                if (w < 0) { if (errno == EINTR) continue; if (errno == EAGAIN) { usleep(100); continue; } c.write_errors++; break; }
                off += (size_t)w;
            }
            c.nav_out++;
        }
        memmove(buf, buf + i, have - i);
        have -= i;
    }
    fprintf(stderr, "gyro_nav: imu_frames=%lu mag_frames=%lu other_frames=%lu crc_errors=%lu length_errors=%lu "
                    "garbage_bytes=%lu nav_frames_out=%lu write_errors=%lu\n", c.frames, c.mag_frames, c.other_frames,
            c.crc_errors, c.length_errors, c.garbage, c.nav_out, c.write_errors);
    return 0;
usage:
    fprintf(stderr, "usage: gyro_nav --imu PATH --host PATH --attitude HEADING,PITCH,ROLL --position LAT,LON,HEIGHT\n");
    return 2;
}
