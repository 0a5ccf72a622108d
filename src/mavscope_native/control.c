/* ControlSources (analysis/control.py) with Systems (analysis/vehicles.py) and mode names
 * (mavlink/modes.py), step for step. Mode names are made here, from the plan's enums, because the
 * detector compares them; labels (a message name, or a command's) stay codes until Python writes them. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "acc.h"

#define LABEL_COMMAND 0x40000000u /* a label that is MAV_CMD `command`'s name; else a message id */

static size_t put(char *out, size_t at, const char *s, size_t n) {
    if (at + n >= MS_MODE_MAX)
        n = at < MS_MODE_MAX - 1 ? MS_MODE_MAX - 1 - at : 0; /* never: names are at most 255 bytes */
    memcpy(out + at, s, n);
    out[at + n] = 0;
    return at + n;
}

/* A whole non-negative number as Python prints it (doubles: integral, any size; %.0f is exact). */
static size_t put_number(char *out, size_t at, double v) {
    char tmp[400];
    int n = snprintf(tmp, sizeof tmp, "%.0f", v);
    return put(out, at, tmp, n > 0 ? (size_t)n : 0);
}

/* px4_mode_name(main, sub) */
static size_t px4_name(const ms_plan *p, double main, double sub, char *out) {
    const ms_plan_enum *mains = &p->enums[p->n_ardupilot + MS_ENUM_PX4_MAIN];
    if (main == (double)p->k[MS_K_PX4_MAIN_AUTO] || (main == (double)p->k[MS_K_PX4_MAIN_POSCTL] && sub != 0)) {
        const int autos = main == (double)p->k[MS_K_PX4_MAIN_AUTO];
        const ms_plan_enum *subs = &p->enums[p->n_ardupilot + (autos ? MS_ENUM_PX4_AUTO : MS_ENUM_PX4_POSCTL)];
        size_t n = autos ? put(out, 0, "AUTO.", 5) : put(out, 0, "POSCTL.", 7);
        const ms_plan_entry *e = sub < 4294967296.0 ? ms_plan_lookup(subs, (uint64_t)sub) : NULL;
        if (e != NULL)
            return put(out, n, e->name, e->len);
        return put_number(out, put(out, n, "sub ", 4), sub);
    }
    const ms_plan_entry *e = main < 4294967296.0 ? ms_plan_lookup(mains, (uint64_t)main) : NULL;
    if (e != NULL)
        return put(out, 0, e->name, e->len);
    return put_number(out, put(out, 0, "main ", 5), main);
}

/* Modes.name(autopilot, mav_type, base_mode, custom_mode): its length; out holds MS_MODE_MAX bytes. */
size_t ms_mode_name(const ms_plan *p, unsigned autopilot, unsigned type, unsigned base, uint64_t custom, char *out) {
    const uint64_t custom_flag = (uint64_t)p->k[MS_K_FLAG_CUSTOM_MODE];
    if (autopilot == p->k[MS_K_AUTOPILOT_PX4] && (base & custom_flag))
        return px4_name(p, (double)((custom >> 16) & 0xFF), (double)((custom >> 24) & 0xFF), out);
    if (base & custom_flag) {
        if (autopilot == p->k[MS_K_AUTOPILOT_ARDUPILOT] && type < 256 && p->ardupilot[type] != 0xFF) {
            const ms_plan_entry *e = ms_plan_lookup(&p->enums[p->ardupilot[type]], custom);
            if (e != NULL)
                return put(out, 0, e->name, e->len);
        }
        return put_number(out, put(out, 0, "custom mode ", 12), (double)custom);
    }
    const ms_plan_entry *e = ms_plan_lookup(&p->enums[p->n_ardupilot + MS_ENUM_MAV_MODE], base);
    if (e != NULL)
        return put(out, 0, e->name, e->len);
    char tmp[32];
    int n = snprintf(tmp, sizeof tmp, "base mode 0x%02x", base);
    return put(out, 0, tmp, n > 0 ? (size_t)n : 0);
}

/* Modes.command_mode: 0 (None) or the name's length + 1 */
static size_t command_mode(const ms_plan *p, unsigned autopilot, unsigned type, const double *params, char *out) {
    for (int i = 0; i < 3; i++)
        if (!isfinite(params[i]) || params[i] != trunc(params[i]))
            return 0; /* int() raises on NaN and infinities; a fraction is no mode */
    double base = trunc(params[0]), main = trunc(params[1]), sub = trunc(params[2]);
    if (!(base >= 0 && base < 256) || main < 0 || sub < 0)
        return 0;
    main += 0.0; /* -0.0 is int 0 */
    sub += 0.0;
    const uint64_t custom_flag = (uint64_t)p->k[MS_K_FLAG_CUSTOM_MODE];
    if (autopilot == p->k[MS_K_AUTOPILOT_PX4]) {
        if ((unsigned)base & custom_flag)
            return px4_name(p, main, sub, out) + 1;
        return ms_mode_name(p, autopilot, type, (unsigned)base, 0, out) + 1;
    }
    return ms_mode_name(p, autopilot, type, (unsigned)base, (uint64_t)fmod(main, 4294967296.0), out) + 1;
}

/* ---- Systems ---------------------------------------------------------------------------------- */

static int is_vehicle_type(const ms_plan *p, unsigned type, unsigned autopilot) {
    return autopilot != p->k[MS_K_AUTOPILOT_INVALID] && !ms_bit(p->not_vehicles, type);
}

static const ms_hb *last_hb(const ms_acc *a, unsigned sender) {
    return a->hb_of[sender] >= 0 ? &a->hbs.v[a->hb_of[sender]] : NULL;
}

/* Systems.see: the HEARTBEAT recorded; 1 when its fields make a Heartbeat */
static int systems_see(ms_acc *a, const ms_acc_frame *f, const ms_plan_msg *pm, ms_hb *hb) {
    static const int SLOTS[5] = {MS_F_TYPE, MS_F_AUTOPILOT, MS_F_BASE_MODE, MS_F_CUSTOM_MODE, MS_F_SYSTEM_STATUS};
    int64_t v[5];
    for (int i = 0; i < 5; i++) {
        ms_val x = ms_get(f, pm, SLOTS[i]);
        if (!x.has || x.is_float)
            return 0; /* never with the plan's types: int(...) of a missing field */
        v[i] = x.i;
    }
    hb->type = (uint8_t)v[0];
    hb->autopilot = (uint8_t)v[1];
    hb->base_mode = (uint8_t)v[2];
    hb->custom_mode = (uint32_t)v[3];
    hb->system_status = (uint8_t)v[4];
    const unsigned sender = (f->sysid << 8) | f->compid;
    if (a->hb_of[sender] < 0) {
        if (a->hbs.n >= (uint32_t)a->plan->k[MS_K_MAX_SENDERS])
            return 1;
        int g = MS_VGROW(a, a->hbs, (uint32_t)a->plan->k[MS_K_MAX_SENDERS]);
        if (g != 0)
            return -1;
        a->hb_of[sender] = (int32_t)a->hbs.n++;
    }
    a->hbs.v[a->hb_of[sender]] = *hb;
    if (ms_bit(a->plan->gcs, hb->type)) {
        a->sys_gcs[f->sysid >> 3] |= (uint8_t)(1u << (f->sysid & 7));
    } else if (is_vehicle_type(a->plan, hb->type, hb->autopilot)) {
        int32_t known = a->vehicle_addr[f->sysid];
        if (known < 0)
            a->vehicle_order[a->nvehicles++] = (uint8_t)f->sysid;
        if (known < 0 || ((known & 0xFF) != 1 && f->compid == 1))
            a->vehicle_addr[f->sysid] = (int32_t)sender;
    }
    return 1;
}

/* ---- ControlSources --------------------------------------------------------------------------- */

static ms_control *vehicle(ms_acc *a, unsigned sysid) {
    ms_control *c = &a->control[sysid]; /* at most 256 < MAX_SENDERS */
    if (!c->exists) {
        memset(c, 0, sizeof *c);
        c->exists = 1;
    }
    return c;
}

static ms_ctl_event *ctl_event(ms_acc *a, int kind) {
    if (MS_VGROW(a, a->ctl_events, MS_CAP_ITEMS) != 0)
        return NULL;
    ms_ctl_event *e = &a->ctl_events.v[a->ctl_events.n++];
    memset(e, 0, sizeof *e);
    e->kind = (uint8_t)kind;
    return e;
}

#define EVENT_OR_FULL(e, kind)                                           \
    ms_ctl_event *e = ctl_event(a, kind);                                \
    if (e == NULL)                                                       \
        return a->ctl_events.cap < MS_CAP_ITEMS ? -1 : 1

static int fresh(const ms_acc_frame *f, int has_t, double t, double limit) {
    if (!has_t || !f->has_time)
        return 1;
    double d = f->time - t;
    return 0 <= d && d <= limit;
}

static int disarmed(ms_acc *a, const ms_acc_frame *f, ms_control *c, const ms_hb *hb) {
    const ms_plan *p = a->plan;
    if (!ms_bit(p->aerial, hb->type))
        return 0;
    const double limit = p->d[MS_D_STATE_FRESH_S];
    int why = -1; /* 0: altitude, 1: the landed state */
    if (c->has_landed && c->landed != p->k[MS_K_LANDED_UNDEFINED] && fresh(f, c->landed_has_t, c->landed_t, limit)) {
        if (c->landed == p->k[MS_K_LANDED_IN_AIR] || c->landed == p->k[MS_K_LANDED_TAKEOFF])
            why = 1;
    } else if (c->has_alt && c->alt > p->d[MS_D_ALT_FLYING_M] && fresh(f, c->alt_has_t, c->alt_t, limit)) {
        why = 0;
    }
    if (why < 0)
        return 0;
    EVENT_OR_FULL(e, 2);
    e->vehicle = (uint8_t)f->sysid;
    e->why = (uint8_t)why;
    e->label = why ? (uint32_t)c->landed : 0;
    e->alt = c->alt;
    e->record = f->record;
    if (c->has_disarm && fresh(f, c->disarm_has_t, c->disarm_t, limit)) {
        e->flag = 1;
        e->sender = c->disarm_sender;
        e->req_record = c->disarm_record;
    }
    return 0;
}

static int heartbeat(ms_acc *a, const ms_acc_frame *f, const ms_plan_msg *pm) {
    ms_hb hb;
    int r = systems_see(a, f, pm, &hb);
    if (r <= 0)
        return r;
    const unsigned sender = (f->sysid << 8) | f->compid;
    if (a->vehicle_addr[f->sysid] != (int32_t)sender)
        return 0;
    ms_control *c = vehicle(a, f->sysid);
    char mode[MS_MODE_MAX];
    size_t n = ms_mode_name(a->plan, hb.autopilot, hb.type, hb.base_mode, hb.custom_mode, mode);
    if (c->has_request && c->req_has_time && f->has_time && f->time - c->req_time > a->plan->d[MS_D_MODE_WINDOW_S])
        c->has_request = 0; /* not followed in time */
    if (c->mode_len && (n != c->mode_len || memcmp(mode, c->mode, n) != 0) && c->has_request &&
        n == c->req_mode_len && memcmp(mode, c->req_mode, n) == 0) {
        if (c->has_holder && c->req_sender != c->holder) {
            EVENT_OR_FULL(e, 1);
            e->vehicle = (uint8_t)f->sysid;
            e->record = f->record;
            e->sender = c->req_sender;
            e->label = c->req_label;
            e->req_record = c->req_record;
            e->holder = c->holder;
            e->old_len = c->mode_len;
            memcpy(e->old_mode, c->mode, c->mode_len);
            e->new_len = (uint16_t)n;
            memcpy(e->new_mode, mode, n);
        }
        c->has_request = 0;
    }
    const int armed = (hb.base_mode & (uint64_t)a->plan->k[MS_K_FLAG_SAFETY_ARMED]) != 0;
    if (c->armed && !armed) {
        if ((r = disarmed(a, f, c, &hb)) != 0)
            return r;
        c->has_holder = 0; /* control passes on after a disarm */
    }
    c->armed = (uint8_t)armed;
    c->mode_len = (uint16_t)n;
    memcpy(c->mode, mode, n);
    return 0;
}

static int control(ms_acc *a, const ms_acc_frame *f, const ms_plan_msg *pm, unsigned vehicle_id) {
    const ms_plan *p = a->plan;
    const int is_command = pm->kind == MS_M_COMMAND_LONG || pm->kind == MS_M_COMMAND_INT;
    ms_val command = is_command ? ms_get(f, pm, MS_F_COMMAND) : (ms_val){0, 0, 0, 0.0};
    if (command.has && (command.is_float || command.i < 0 || command.i > 65535 ||
                        !ms_bit(p->control_commands, (unsigned)command.i)))
        return 0;
    ms_val mt = ms_get(f, pm, MS_F_MISSION_TYPE);
    int64_t mtype = mt.has ? mt.i : p->k[MS_K_MISSION_TYPE_MISSION]; /* fields.get("mission_type", MISSION) */
    ms_val count = ms_get(f, pm, MS_F_COUNT);
    int clear = (pm->kind == MS_M_MISSION_CLEAR_ALL &&
                 (mtype == p->k[MS_K_MISSION_TYPE_MISSION] || mtype == p->k[MS_K_MISSION_TYPE_ALL])) ||
                (pm->kind == MS_M_MISSION_COUNT && count.has && count.i == 0 && mtype == p->k[MS_K_MISSION_TYPE_MISSION]);
    const unsigned sender = (f->sysid << 8) | f->compid;
    if (pm->kind == MS_M_MISSION_COUNT) {
        const ms_hb *hb = last_hb(a, sender);
        if (hb != NULL && is_vehicle_type(p, hb->type, hb->autopilot))
            return 0; /* a vehicle sending its mission (a download) controls nothing */
    }
    ms_control *c = vehicle(a, vehicle_id);
    const uint32_t label = command.has ? LABEL_COMMAND | (uint32_t)command.i : f->msgid;
    if (command.has && command.i == p->k[MS_K_CMD_ARM_DISARM]) {
        ms_val p1 = ms_get(f, pm, MS_F_PARAM1);
        if (p1.has && p1.d == 0) {
            c->has_disarm = 1;
            c->disarm_sender = (uint8_t)f->sysid;
            c->disarm_record = f->record;
            c->disarm_has_t = (uint8_t)f->has_time;
            c->disarm_t = f->time;
        }
    }
    if (!c->has_holder) {
        c->has_holder = 1;
        c->holder = (uint8_t)f->sysid;
        c->since = f->record;
        return 0;
    }
    if (c->holder == f->sysid)
        return 0;
    if (pm->kind == MS_M_SET_MODE || (command.has && command.i == p->k[MS_K_CMD_DO_SET_MODE])) {
        /* _asked: the mode named as the vehicle's HEARTBEAT would name it */
        const ms_hb *hb = a->vehicle_addr[vehicle_id] >= 0 ? last_hb(a, (unsigned)a->vehicle_addr[vehicle_id]) : NULL;
        unsigned autopilot = hb ? hb->autopilot : 0, type = hb ? hb->type : 0;
        char mode[MS_MODE_MAX];
        size_t n = 0;
        if (pm->kind == MS_M_SET_MODE) {
            ms_val base = ms_get(f, pm, MS_F_BASE_MODE), custom = ms_get(f, pm, MS_F_CUSTOM_MODE);
            if (base.has && !base.is_float && custom.has && !custom.is_float)
                n = ms_mode_name(p, autopilot, type, (unsigned)base.i, (uint64_t)custom.i, mode) + 1;
        } else {
            ms_val v[3] = {ms_get(f, pm, MS_F_PARAM1), ms_get(f, pm, MS_F_PARAM2), ms_get(f, pm, MS_F_PARAM3)};
            if (v[0].has && v[1].has && v[2].has) {
                double params[3] = {v[0].d, v[1].d, v[2].d};
                n = command_mode(p, autopilot, type, params, mode);
            }
        }
        if (n) {
            c->has_request = 1;
            c->req_sender = (uint8_t)f->sysid;
            c->req_label = label;
            c->req_record = f->record;
            c->req_has_time = (uint8_t)f->has_time;
            c->req_time = f->time;
            c->req_mode_len = (uint16_t)(n - 1);
            memcpy(c->req_mode, mode, n - 1);
        }
    }
    if (clear) {
        EVENT_OR_FULL(e, 0);
        e->sender = (uint8_t)f->sysid;
        e->vehicle = (uint8_t)vehicle_id;
        e->flag = pm->kind == MS_M_MISSION_CLEAR_ALL;
        e->record = f->record;
        e->holder = c->holder;
        e->since = c->since;
    }
    if (c->armed) {
        const uint32_t key = vehicle_id << 8 | f->sysid;
        uint32_t at;
        int32_t slot = -1;
        if (ms_map_get(&a->intrusion_index, key, &at)) {
            slot = (int32_t)at;
        } else {
            if (a->intrusions.n >= (uint32_t)p->k[MS_K_MAX_SENDERS])
                return 0;
        }
        int fresh_entry = slot < 0;
        int r = ms_count_named(a, &slot, &a->intrusions, key, &f->record, 1, label);
        if (r != 0)
            return r;
        if (fresh_entry) {
            a->named.v[slot].holder = c->holder;
            a->named.v[slot].since = c->since;
            if (ms_map_put(&a->intrusion_index, key, (uint32_t)slot) != 0)
                return -1;
        }
    }
    return 0;
}

int ms_control_add(ms_acc *a, const ms_acc_frame *f, const ms_plan_msg *pm) {
    if (pm->kind == MS_M_HEARTBEAT)
        return heartbeat(a, f, pm);
    if (pm->kind == MS_M_EXTENDED_SYS_STATE || pm->kind == MS_M_GLOBAL_POSITION_INT) {
        ms_control *c = a->vehicle_addr[f->sysid] >= 0 && a->control[f->sysid].exists ? &a->control[f->sysid] : NULL;
        if (c == NULL)
            return 0;
        ms_val landed = ms_get(f, pm, MS_F_LANDED_STATE), alt = ms_get(f, pm, MS_F_RELATIVE_ALT);
        if (pm->kind == MS_M_EXTENDED_SYS_STATE && landed.has && !landed.is_float) {
            c->has_landed = 1;
            c->landed = landed.i;
            c->landed_has_t = (uint8_t)f->has_time;
            c->landed_t = f->time;
        } else if (alt.has && !alt.is_float) {
            c->has_alt = 1;
            c->alt = (double)alt.i / 1000;
            c->alt_has_t = (uint8_t)f->has_time;
            c->alt_t = f->time;
        }
        return 0;
    }
    ms_val t = ms_get(f, pm, pm->kind == MS_M_MANUAL_CONTROL ? MS_F_TARGET : MS_F_TARGET_SYSTEM);
    if (!t.has || t.is_float || t.i < 0 || t.i > 255)
        return 0; /* not an int (the plan allows uint8 only) */
    const unsigned target = (unsigned)t.i;
    if (target == f->sysid || ms_bit(a->sys_gcs, target))
        return 0;
    if (target)
        return control(a, f, pm, target);
    /* a broadcast: every vehicle known but the sender, in the order they were first seen */
    const uint32_t n = a->nvehicles;
    for (uint32_t i = 0; i < n; i++) {
        unsigned v = a->vehicle_order[i];
        if (v == f->sysid)
            continue;
        int r = control(a, f, pm, v);
        if (r != 0)
            return r;
    }
    return 0;
}
