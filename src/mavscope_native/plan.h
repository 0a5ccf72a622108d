/* The statistics plan: what the native `stats` accumulator (acc.h) needs to know of the dialect and of
 * the Python analyses, compiled in Python by mavscope/native_stats.py (never written by hand here).
 *
 * Blob layout (little-endian): "MSSP", u32 version (1), then
 *   u16 n_ints, i64[n_ints]: the analyses' integer constants in the order of MS_K_* below;
 *   u16 n_doubles, f64[n_doubles]: their float constants in the order of MS_D_*;
 *   u32 n_messages, per message: u32 msgid, u8 kind (MS_M_*), u8 roles (MS_R_*), then MS_NSLOTS x
 *     (u8 type (table.h MS_T_*, 0: the message has no such field), u8 offset in the padded payload);
 *   three 32-byte bitmaps of MAV_TYPE values (< 256): aerial, ground stations, not vehicles;
 *   256 bytes: per MAV_TYPE the index of its ArduPilot mode enum (0xFF: none);
 *   u8 n_enums, the enums: ArduPilot's mode enums (by index), then MAV_MODE, PX4's main modes, PX4's
 *     AUTO sub modes, PX4's POSCTL sub modes (MS_ENUM_* below); each u32 n_entries, then per entry
 *     (strictly increasing value) u32 value, u8 name length, the name (prefix already removed);
 *   8192 bytes: bitmap of the MAV_CMD values that are control commands (analysis/control.py);
 *   8 x u64: EKF_STATUS_FLAGS (healthy, glitch, absolute position, uninitialised), then
 *     ESTIMATOR_STATUS_FLAGS the same.
 * ms_plan_parse checks every length, kind, type and offset. No Python API here. */
#ifndef MAVSCOPE_NATIVE_PLAN_H
#define MAVSCOPE_NATIVE_PLAN_H

#include <stddef.h>
#include <stdint.h>

#define MS_RING 8      /* sequence.RING: the size of acc.h ms_counter's ring */
#define MS_SHOWN_MAX 8 /* the largest MS_K_COMMANDERS_SHOWN (acc.h ms_commanded's arrays) */

/* integer constants (mavscope.analysis: sequence, stats, expert, commanders, vehicles, control, gnss,
   framelist) */
enum {
    MS_K_GAP_MIN, MS_K_GAPS_KEPT, MS_K_RESET_RUN, MS_K_MAX_CHANNELS, MS_K_MAX_EXTRA, MS_K_LATE_WINDOW,
    MS_K_RATE_BINS, MS_K_COPIES_KEPT, MS_K_MAX_SENDERS, MS_K_MAX_FRAMES, MS_K_MAV_TYPE_GCS,
    MS_K_CMD_DO_SET_MODE, MS_K_CMD_ARM_DISARM, MS_K_MISSION_TYPE_MISSION, MS_K_MISSION_TYPE_ALL,
    MS_K_LANDED_IN_AIR, MS_K_LANDED_TAKEOFF, MS_K_LANDED_UNDEFINED, MS_K_AUTOPILOT_ARDUPILOT,
    MS_K_AUTOPILOT_INVALID, MS_K_AUTOPILOT_PX4, MS_K_FLAG_SAFETY_ARMED, MS_K_FLAG_CUSTOM_MODE,
    MS_K_PX4_MAIN_AUTO, MS_K_PX4_MAIN_POSCTL, MS_K_FIX_NO_GPS, MS_K_FIX_NO_FIX, MS_K_FIX_2D, MS_K_FIX_3D,
    MS_K_UNKNOWN_SATS, MS_K_UNKNOWN_VEL, MS_K_MIN_SATS, MS_K_UNIX_MIN_US, MS_K_MAX_STREAMS,
    MS_K_MAX_CONVERSATIONS, MS_K_MAX_NAMED, MS_K_COMMANDERS_SHOWN, MS_K_RING, MS_K_MAX_EPISODES,
    MS_K_COUNT
};

/* float constants */
enum {
    MS_D_MODE_WINDOW_S, MS_D_STATE_FRESH_S, MS_D_ALT_FLYING_M, MS_D_EARTH_RADIUS_M, MS_D_JUMP_MIN_M,
    MS_D_SPEED_FACTOR, MS_D_ACCEL_MPS2, MS_D_MARGIN_M, MS_D_NULL_ISLAND, MS_D_MAX_GAP_S, MS_D_COLLAPSE_WINDOW_S,
    MS_D_VARIANCE_ALARM, MS_D_TIME_JUMP_S, MS_D_TIME_MISMATCH_S, MS_D_REBOOT_BACK_S,
    MS_D_COUNT
};

/* message kinds: the names the analyses test for (MS_M_OTHER: another commanding message) */
enum {
    MS_M_NONE, MS_M_OTHER, MS_M_HEARTBEAT, MS_M_EXTENDED_SYS_STATE, MS_M_GLOBAL_POSITION_INT, MS_M_GPS_RAW_INT,
    MS_M_GPS2_RAW, MS_M_SYSTEM_TIME, MS_M_EKF_STATUS_REPORT, MS_M_ESTIMATOR_STATUS, MS_M_SET_MODE,
    MS_M_COMMAND_LONG, MS_M_COMMAND_INT, MS_M_MISSION_CLEAR_ALL, MS_M_MISSION_COUNT, MS_M_MANUAL_CONTROL,
    MS_M_COUNT
};

/* roles: which analyses look at the message's fields */
enum {
    MS_R_DECODE = 1,     /* Expert.decode: its fields are decoded for the detectors */
    MS_R_COMMANDING = 2, /* expert.COMMANDING */
    MS_R_CONTROL = 4,    /* control.WANTS */
    MS_R_GNSS = 8,       /* gnss.WANTS */
};

/* field slots: the fields the analyses read, by name */
enum {
    MS_F_TARGET_SYSTEM, MS_F_TARGET, MS_F_TYPE, MS_F_AUTOPILOT, MS_F_BASE_MODE, MS_F_CUSTOM_MODE,
    MS_F_SYSTEM_STATUS, MS_F_COMMAND, MS_F_PARAM1, MS_F_PARAM2, MS_F_PARAM3, MS_F_MISSION_TYPE, MS_F_COUNT,
    MS_F_LANDED_STATE, MS_F_RELATIVE_ALT, MS_F_LAT, MS_F_LON, MS_F_VX, MS_F_VY, MS_F_TIME_BOOT_MS,
    MS_F_TIME_USEC, MS_F_FIX_TYPE, MS_F_VEL, MS_F_H_ACC, MS_F_SATELLITES_VISIBLE, MS_F_FLAGS,
    MS_F_VELOCITY_VARIANCE, MS_F_POS_HORIZ_VARIANCE, MS_F_VEL_RATIO, MS_F_POS_HORIZ_RATIO, MS_F_TIME_UNIX_USEC,
    MS_NSLOTS
};

enum { MS_ENUM_MAV_MODE, MS_ENUM_PX4_MAIN, MS_ENUM_PX4_AUTO, MS_ENUM_PX4_POSCTL, MS_ENUM_FIXED }; /* after ArduPilot's */

#define MS_NAME_MAX 255

typedef struct {
    uint32_t value;
    uint8_t len;
    const char *name;
} ms_plan_entry;

typedef struct {
    ms_plan_entry *v;
    uint32_t n;
} ms_plan_enum;

typedef struct {
    uint8_t type;
    uint8_t offset;
} ms_slot;

typedef struct {
    uint32_t msgid;
    uint8_t kind;
    uint8_t roles;
    ms_slot slots[MS_NSLOTS];
} ms_plan_msg;

typedef struct {
    int64_t k[MS_K_COUNT];
    double d[MS_D_COUNT];
    ms_plan_msg *msgs;
    uint32_t nmsgs;
    int32_t *slots; /* open addressing msgid -> index in msgs, or -1 */
    uint32_t nslots;
    uint8_t aerial[32], gcs[32], not_vehicles[32];
    uint8_t ardupilot[256];
    ms_plan_enum *enums; /* n_ardupilot ArduPilot enums, then MS_ENUM_FIXED more */
    uint32_t n_ardupilot;
    uint8_t control_commands[8192];
    uint64_t ekf_bits[4], est_bits[4];
    char *text;
} ms_plan;

int ms_plan_parse(ms_plan *p, const uint8_t *blob, size_t len);
void ms_plan_free(ms_plan *p);

static inline const ms_plan_msg *ms_plan_get(const ms_plan *p, uint32_t msgid) {
    uint32_t mask = p->nslots - 1;
    uint32_t i = (msgid * 2654435761u) & mask;
    for (;;) {
        int32_t k = p->slots[i];
        if (k < 0)
            return NULL;
        if (p->msgs[k].msgid == msgid)
            return &p->msgs[k];
        i = (i + 1) & mask;
    }
}

static inline int ms_bit(const uint8_t *map, unsigned v) {
    return (map[v >> 3] >> (v & 7)) & 1;
}

/* The entry of `value` in enum e, or NULL. */
const ms_plan_entry *ms_plan_lookup(const ms_plan_enum *e, uint64_t value);

#endif
