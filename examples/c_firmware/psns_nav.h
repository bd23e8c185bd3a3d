/* psns_nav: the example firmware's own declarations next to the lockstep interface it implements (psns_nav.c). */
#ifndef PSNS_NAV_H
#define PSNS_NAV_H

#include "psns_fw.h"

/* what the decoder skipped and the firmware did, for the programs' exit line (stderr) */
typedef struct psns_nav_counters {
    uint64_t imu_frames, mag_frames, other_frames, crc_errors, length_errors, garbage_bytes, ring_overflow_bytes,
        other_uart_bytes, nav_frames_out, tx_overflow_frames, time_jumps;
} psns_nav_counters;

const psns_nav_counters *psns_nav_get_counters(void);

#endif /* PSNS_NAV_H */
