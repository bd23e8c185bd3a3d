/*
 * psns_nav_lockstep: the example firmware (psns_nav.c) as an out-of-process lockstep firmware: the framing of
 * docs/icd.md section 10.3 on stdin (requests) and stdout (replies); diagnostics on stderr only.
 *
 * Scenario: dsp: {external: {lockstep: {command: [build/psns_nav_lockstep]}}}, run with --allow-firmware.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "psns_nav.h"

#define MAX_REQUEST (1u << 20)
#define TX_CAP_MAX 65536u

static uint8_t req[MAX_REQUEST];
static uint8_t tx[PSNS_FW_UARTS * TX_CAP_MAX];
static uint8_t reply[8 + 32 + PSNS_FW_UARTS * TX_CAP_MAX];

static uint32_t rd32(const uint8_t *p) {
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}
static uint64_t rd64(const uint8_t *p) { return (uint64_t)rd32(p) | ((uint64_t)rd32(p + 4) << 32); }
static void wr32(uint8_t *p, uint32_t v) { for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i)); }
static void wr64(uint8_t *p, uint64_t v) { wr32(p, (uint32_t)v); wr32(p + 4, (uint32_t)(v >> 32)); }

static int read_exact(uint8_t *p, size_t n) { return fread(p, 1, n, stdin) == n; }

static void send_reply(char type, size_t n) {
    reply[0] = (uint8_t)type; reply[1] = PSNS_FW_ABI_VERSION; reply[2] = reply[3] = 0;
    wr32(reply + 4, (uint32_t)n);
    fwrite(reply, 1, 8 + n, stdout);
    fflush(stdout);
}

int main(void) {
    uint8_t head[8];
    while (read_exact(head, 8)) {
        uint32_t n = rd32(head + 4);
        if (n > MAX_REQUEST || !read_exact(req, n)) { fprintf(stderr, "psns_nav_lockstep: bad request\n"); return 2; }
        switch (head[0]) {
        case 'I': {
            psns_fw_config cfg;
            if (n < sizeof cfg) return 2;
            memcpy(&cfg, req, sizeof cfg); /* little-endian host: the wire layout is the struct's */
            int32_t st = psns_fw_init(&cfg);
            wr32(reply + 8, psns_fw_abi_version());
            wr32(reply + 12, (uint32_t)st);
            send_reply('i', 8);
            break;
        }
        case 'R':
            if (n < 16) return 2;
            psns_fw_rx(rd32(req), req + 16, n - 16, rd64(req + 8));
            break;
        case 'S': {
            if (n < 16) return 2;
            uint32_t cap = rd32(req + 8);
            if (cap > TX_CAP_MAX) cap = TX_CAP_MAX;
            uint32_t len[PSNS_FW_UARTS];
            uint64_t cycles = 0;
            int32_t st = psns_fw_step(rd64(req), tx, cap, len, &cycles);
            uint8_t *p = reply + 8;
            wr32(p, (uint32_t)st); wr32(p + 4, 0); wr64(p + 8, cycles);
            size_t off = 32;
            for (uint32_t k = 0; k < PSNS_FW_UARTS; k++) {
                wr32(p + 16 + 4 * k, len[k]);
                memcpy(p + off, tx + (size_t)k * cap, len[k]);
                off += len[k];
            }
            send_reply('s', off);
            break;
        }
        case 'Q':
            goto done;
        default:
            fprintf(stderr, "psns_nav_lockstep: unknown request 0x%02x\n", head[0]);
            return 2;
        }
    }
done:
    psns_fw_close();
    {
        const psns_nav_counters *c = psns_nav_get_counters();
        fprintf(stderr, "psns_nav_lockstep: imu_frames=%llu crc_errors=%llu garbage_bytes=%llu nav_frames_out=%llu\n",
                (unsigned long long)c->imu_frames, (unsigned long long)c->crc_errors,
                (unsigned long long)c->garbage_bytes, (unsigned long long)c->nav_frames_out);
    }
    return 0;
}
