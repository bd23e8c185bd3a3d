/*
 * faulty_firmware: a lockstep firmware process (docs/icd.md section 10.3) that behaves for N steps and then
 * misbehaves, for the containment tests of tests/emulator/dsp/test_lockstep_robustness.py.
 *
 * Usage: faulty_firmware MODE N
 *   crash        dereferences a null pointer at step N (SIGSEGV)
 *   hang         loops forever at step N (never replies)
 *   exit         exits with status 3 at step N
 *   garbage      writes 64 bytes of garbage on stdout instead of the reply to step N
 *   oversize     replies to step N with a tx_len above tx_cap
 *   flood        replies to every step from N on with tx_cap bytes of 0x55 on UART0 (within the contract)
 *   uart_garbage replies to every step from N on with 200 bytes that are no host frame on UART0
 * Before step N every step reports 1000 cycles and no output.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static uint8_t req[1 << 20];
static uint8_t tx[8 + 32 + 65536];

static uint32_t rd32(const uint8_t *p) {
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}
static void wr32(uint8_t *p, uint32_t v) { for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i)); }

static void reply(char type, uint32_t n) {
    tx[0] = (uint8_t)type; tx[1] = 1; tx[2] = tx[3] = 0; wr32(tx + 4, n);
    fwrite(tx, 1, 8 + n, stdout);
    fflush(stdout);
}

int main(int argc, char **argv) {
    if (argc != 3) return 2;
    const char *mode = argv[1];
    long n_bad = atol(argv[2]);
    long steps = 0;
    uint8_t head[8];
    while (fread(head, 1, 8, stdin) == 8) {
        uint32_t n = rd32(head + 4);
        if (n > sizeof req || fread(req, 1, n, stdin) != n) return 2;
        if (head[0] == 'Q') return 0;
        if (head[0] == 'I') { wr32(tx + 8, 1); wr32(tx + 12, 0); reply('i', 8); continue; }
        if (head[0] != 'S') continue;
        uint32_t cap = rd32(req + 8);
        memset(tx + 8, 0, 32);
        wr32(tx + 16, 1000); /* cycles, low word */
        uint32_t len0 = 0;
        if (++steps >= n_bad) {
            if (!strcmp(mode, "crash")) { volatile int *p = NULL; *p = 1; }
            if (!strcmp(mode, "hang")) { volatile unsigned long x = 0; for (;;) x++; }
            if (!strcmp(mode, "exit")) exit(3);
            if (!strcmp(mode, "garbage")) {
                for (int i = 0; i < 64; i++) tx[i] = (uint8_t)(i * 37 + 11);
                fwrite(tx, 1, 64, stdout); fflush(stdout);
                continue;
            }
            if (!strcmp(mode, "oversize")) { wr32(tx + 24, cap + 1); reply('s', 32); continue; }
            if (!strcmp(mode, "flood")) { len0 = cap < 65536 ? cap : 65536; memset(tx + 40, 0x55, len0); }
            if (!strcmp(mode, "uart_garbage")) { len0 = 200; for (uint32_t i = 0; i < len0; i++) tx[40 + i] = (uint8_t)(i * 13 + 7); }
        }
        wr32(tx + 24, len0);
        reply('s', 32 + len0);
    }
    return 0;
}
