/*
 * psns_nav_pty: the example firmware (psns_nav.c) in the "DSP out" mode over ptys or serial ports in realtime
 * (docs/runtime.md, section DSP out): the same psns_fw_* calls as in lockstep, driven by the bytes that arrive on
 * the IMU port and the host's monotonic clock.
 *
 * Usage: psns_nav_pty --imu PATH --host PATH --attitude HEADING,PITCH,ROLL --position LAT,LON,HEIGHT
 *        [--gyro-incremental]
 *   PATH are serial devices or the emulator's pty symlinks (<run_dir>/ports/NAME). It runs until its IMU port
 *   hangs up (the emulator closed the port) or it gets SIGTERM / SIGINT; its counters go to stderr at exit.
 */
#define _DEFAULT_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "psns_nav.h"

#define TX_CAP 8192u

static volatile sig_atomic_t stop_requested = 0;
static void on_signal(int sig) { (void)sig; stop_requested = 1; }

static int open_port(const char *path, int flags) {
    int fd = open(path, flags | O_NOCTTY);
    if (fd < 0) { fprintf(stderr, "psns_nav_pty: cannot open %s: %s\n", path, strerror(errno)); exit(2); }
    struct termios t;
    if (tcgetattr(fd, &t) == 0) { /* a real serial port: raw 8N1 at 460800 (a pty ignores the speed) */
        cfmakeraw(&t);
        cfsetispeed(&t, B460800); cfsetospeed(&t, B460800);
        t.c_cflag |= CLOCAL | CREAD;
        tcsetattr(fd, TCSANOW, &t);
    }
    return fd;
}

static uint64_t now_us(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

int main(int argc, char **argv) {
    const char *imu_path = NULL, *host_path = NULL;
    psns_fw_config cfg = {PSNS_FW_ABI_VERSION, 300000000u, 200u, 0u, 0, 0, 0, 0, 0, 0};
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--gyro-incremental")) { cfg.flags |= PSNS_FW_FLAG_GYRO_INCREMENTAL; continue; }
        if (i + 1 >= argc) goto usage;
        if (!strcmp(argv[i], "--imu")) imu_path = argv[++i];
        else if (!strcmp(argv[i], "--host")) host_path = argv[++i];
        else if (!strcmp(argv[i], "--attitude")) {
            if (sscanf(argv[++i], "%lf,%lf,%lf", &cfg.heading_deg, &cfg.pitch_deg, &cfg.roll_deg) != 3) goto usage;
        } else if (!strcmp(argv[i], "--position")) {
            if (sscanf(argv[++i], "%lf,%lf,%lf", &cfg.lat_deg, &cfg.lon_deg, &cfg.height_m) != 3) goto usage;
        } else goto usage;
    }
    if (!imu_path || !host_path) goto usage;
    signal(SIGTERM, on_signal); signal(SIGINT, on_signal); signal(SIGPIPE, SIG_IGN);
    int in_fd = open_port(imu_path, O_RDONLY | O_NONBLOCK);
    int out_fd = strcmp(imu_path, host_path) ? open_port(host_path, O_WRONLY) : in_fd;
    if (psns_fw_init(&cfg) != PSNS_FW_OK) { fprintf(stderr, "psns_nav_pty: init failed\n"); return 2; }

    static uint8_t tx[PSNS_FW_UARTS * TX_CAP];
    uint8_t buf[4096];
    unsigned long write_errors = 0;
    while (!stop_requested) {
        struct pollfd p = {in_fd, POLLIN, 0};
        int r = poll(&p, 1, 200);
        if (r < 0) { if (errno == EINTR) continue; break; }
        if (r == 0) continue;
        if (p.revents & POLLIN) {
            ssize_t n = read(in_fd, buf, sizeof buf);
            if (n < 0) { if (errno == EAGAIN || errno == EINTR) continue; break; }
            if (n == 0) break;
            uint64_t t = now_us();
            psns_fw_rx(1, buf, (uint32_t)n, t);
            uint32_t len[PSNS_FW_UARTS];
            uint64_t cycles;
            if (psns_fw_step(t, tx, TX_CAP, len, &cycles) != PSNS_FW_OK) continue;
            size_t off = 0;
            while (off < len[0]) { /* UART0: the host port */
                ssize_t w = write(out_fd, tx + off, len[0] - off);
                if (w < 0) {
                    if (errno == EINTR) continue;
                    if (errno == EAGAIN) { usleep(100); continue; }
                    write_errors++;
                    break;
                }
                off += (size_t)w;
            }
        } else if (p.revents & (POLLHUP | POLLERR)) {
            break; /* the emulator closed the port: the run is over */
        }
    }
    psns_fw_close();
    const psns_nav_counters *c = psns_nav_get_counters();
    fprintf(stderr, "psns_nav_pty: imu_frames=%llu mag_frames=%llu other_frames=%llu crc_errors=%llu "
                    "length_errors=%llu garbage_bytes=%llu nav_frames_out=%llu write_errors=%lu\n",
            (unsigned long long)c->imu_frames, (unsigned long long)c->mag_frames,
            (unsigned long long)c->other_frames, (unsigned long long)c->crc_errors,
            (unsigned long long)c->length_errors, (unsigned long long)c->garbage_bytes,
            (unsigned long long)c->nav_frames_out, write_errors);
    return 0;
usage:
    fprintf(stderr, "usage: psns_nav_pty --imu PATH --host PATH --attitude HEADING,PITCH,ROLL "
                    "--position LAT,LON,HEIGHT [--gyro-incremental]\n");
    return 2;
}
