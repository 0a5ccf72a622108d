/* GnssAnomalies (analysis/gnss.py), step for step and float operation for float operation: the same
 * IEEE operations in the same order, the C library's sin, cos, asin and pow (Python's math module and
 * float ** call them), Python's radians (x * (pi / 180)) and `x ** 2` (pow(|x|, 2), 0.0 for 0). The
 * build turns FMA contraction off (setup.py). An episode keeps the numbers of its worst sentence;
 * native_stats.py writes the sentence with gnss.py's own functions. */
#include <math.h>
#include <string.h>

#include "acc.h"

#define PY_MATH_PI 3.14159265358979323846 /* Py_MATH_PI: math.radians multiplies by PY_MATH_PI / 180.0 */

static double (*volatile pow_fn)(double, double) = pow; /* the library's pow, never folded into x * x */

static double square(double x) {
    return x == 0.0 ? 0.0 : pow_fn(fabs(x), 2.0);
}

static double radians(double x) {
    return x * (PY_MATH_PI / 180.0);
}

/* gnss.distance_m */
static double distance_m(const ms_plan *p, double lat1, double lon1, double lat2, double lon2) {
    double p1 = radians(lat1), p2 = radians(lat2);
    double dp = p2 - p1, dl = radians(lon2 - lon1);
    double a = square(sin(dp / 2)) + cos(p1) * cos(p2) * square(sin(dl / 2));
    double r = sqrt(a > 0.0 ? a : 0.0); /* max(0.0, a) */
    r = r < 1.0 ? r : 1.0;              /* min(1.0, ...) */
    return 2 * p->d[MS_D_EARTH_RADIUS_M] * asin(r);
}

/* gnss._num: an int or float field, finite, as a float */
static int num(const ms_acc_frame *f, const ms_plan_msg *pm, int slot, double *out) {
    ms_val v = ms_get(f, pm, slot);
    if (!v.has || !isfinite(v.d))
        return 0;
    *out = v.d;
    return 1;
}

static int kind_index(int kind) {
    switch (kind) {
    case MS_M_GLOBAL_POSITION_INT: return MS_G_GPI;
    case MS_M_GPS_RAW_INT: return MS_G_GPS_RAW;
    case MS_M_GPS2_RAW: return MS_G_GPS2_RAW;
    case MS_M_SYSTEM_TIME: return MS_G_SYSTEM_TIME;
    case MS_M_EKF_STATUS_REPORT: return MS_G_EKF;
    case MS_M_ESTIMATOR_STATUS: return MS_G_EST;
    default: return -1;
    }
}

/* GnssAnomalies._note: the episode of (code, sender, message), its frame, and the worst one's numbers. Past
 * the plan's MS_K_MAX_EPISODES (gnss.MAX_EPISODES) the pure path chooses which episodes to give up (the least established
 * senders', said): `full` is set and *err is 1, so the caller runs it. */
static ms_episode *note(ms_acc *a, int code, unsigned sender, int g, uint64_t record, double size, int *err) {
    const uint64_t key = (uint64_t)code << 24 | (uint64_t)g << 16 | sender;
    uint32_t at;
    *err = 0;
    if (!ms_map_get(&a->episode_index, key, &at)) {
        if (a->episodes.n >= (uint32_t)a->plan->k[MS_K_MAX_EPISODES]) {
            a->full = 1;
            *err = 1;
            return NULL;
        }
        if (MS_VGROW(a, a->episodes, (uint32_t)a->plan->k[MS_K_MAX_EPISODES]) != 0 ||
            ms_map_put(&a->episode_index, key, a->episodes.n) != 0) {
            *err = -1;
            return NULL;
        }
        at = a->episodes.n++;
        ms_episode *e = &a->episodes.v[at];
        memset(e, 0, sizeof *e);
        e->code = (uint8_t)code;
        e->kind = (uint8_t)g;
        e->sender = (uint16_t)sender;
        e->worst = -1.0;
    }
    ms_episode *e = &a->episodes.v[at];
    ms_fn_add(&e->fn, record, (uint32_t)a->plan->k[MS_K_MAX_FRAMES]);
    if (!(size > e->worst))
        return NULL;
    e->worst = size;
    memset(e->a, 0, sizeof e->a);
    memset(e->n, 0, sizeof e->n);
    e->flags = MS_EPISODE_TEXT;
    return e; /* the caller fills the numbers of the new worst sentence */
}

#define NOTE(e, code, size)                                                  \
    int err_;                                                                \
    ms_episode *e = note(a, code, sender, g, f->record, size, &err_);        \
    if (err_)                                                                \
        return err_;                                                         \
    if (e != NULL)

/* _clock: 1 when the message has a clock (or is judged in order), 0 to skip it */
static int clock(ms_acc *a, ms_gsender *s, int g, const ms_acc_frame *f, const ms_plan_msg *pm) {
    const ms_plan *p = a->plan;
    double boot = 0, usec = 0, now;
    int has_boot = num(f, pm, MS_F_TIME_BOOT_MS, &boot), has_usec = num(f, pm, MS_F_TIME_USEC, &usec);
    if (has_boot)
        now = boot / 1000;
    else if (has_usec)
        now = usec / 1e6;
    else
        return g == MS_G_EKF;
    if (s->has_clock[g] && now + p->d[MS_D_REBOOT_BACK_S] <= s->clocks[g] &&
        (!has_usec || usec < (double)p->k[MS_K_UNIX_MIN_US])) {
        for (int i = 0; i < 3; i++)
            s->fixes[i].has = s->has_good[i] = s->collapsed[i] = 0;
        s->ekf_good = s->ekf_alarm = 0;
        s->has_utc = 0;
        memset(s->has_clock, 0, sizeof s->has_clock);
    }
    s->clocks[g] = now;
    s->has_clock[g] = 1;
    if (has_boot) {
        s->boot_s = now;
        s->has_boot = 1;
    }
    return 1;
}

static int gps_time(ms_acc *a, ms_gsender *s, unsigned sender, int g, const ms_acc_frame *f, double usec) {
    if (!s->has_utc || !s->has_boot || s->boot_s < s->utc_b)
        return 0;
    double expected = s->utc_u + (s->boot_s - s->utc_b);
    double diff = usec / 1e6 - expected;
    if (fabs(diff) > a->plan->d[MS_D_TIME_MISMATCH_S]) {
        NOTE(e, MS_GC_TIME, fabs(diff)) {
            e->flags |= 2; /* against SYSTEM_TIME */
            e->a[0] = diff;
            e->n[0] = (int64_t)s->utc_record;
            e->n[1] = (int64_t)f->record;
        }
    }
    return 0;
}

static int fix(ms_acc *a, ms_gsender *s, unsigned sender, int g, const ms_acc_frame *f, double t, int64_t fixv,
               ms_val sats) {
    const ms_plan *p = a->plan;
    int has_nsat = sats.has && !sats.is_float && sats.i != p->k[MS_K_UNKNOWN_SATS];
    int64_t nsat = sats.i;
    if (fixv >= p->k[MS_K_FIX_3D] && (!has_nsat || nsat >= p->k[MS_K_MIN_SATS])) {
        s->has_good[g] = 1;
        s->good_t[g] = t;
        s->good_sats[g] = has_nsat ? nsat : -1;
        s->collapsed[g] = 0;
        return 0;
    }
    if (!s->has_good[g] || s->collapsed[g] || fixv == p->k[MS_K_FIX_NO_GPS])
        return 0;
    double dt = t - s->good_t[g];
    if (!(0 <= dt && dt <= p->d[MS_D_COLLAPSE_WINDOW_S]))
        return 0;
    int weak = fixv == p->k[MS_K_FIX_NO_FIX] || fixv == p->k[MS_K_FIX_2D];
    int64_t good = s->good_sats[g];
    int few = has_nsat && good > 0 && nsat * 2 < good && nsat < p->k[MS_K_MIN_SATS];
    if (weak || few) {
        s->collapsed[g] = 1;
        NOTE(e, MS_GC_COLLAPSE, (double)(good - (has_nsat ? nsat : 0))) {
            e->flags |= (uint8_t)has_nsat;
            e->n[0] = good;
            e->n[1] = nsat;
            e->n[2] = fixv;
            e->n[3] = (int64_t)f->record;
            e->a[0] = dt;
        }
    }
    return 0;
}

static int position(ms_acc *a, ms_gsender *s, unsigned sender, int g, const ms_acc_frame *f, const ms_plan_msg *pm) {
    const ms_plan *p = a->plan;
    double lat = 0, lon = 0, speed = 0, accuracy = 0.0;
    int has_lat = num(f, pm, MS_F_LAT, &lat), has_lon = num(f, pm, MS_F_LON, &lon), has_speed;
    const double t = s->clocks[g];
    if (g == MS_G_GPI) {
        double vx, vy;
        has_speed = num(f, pm, MS_F_VX, &vx) && num(f, pm, MS_F_VY, &vy);
        /* math.hypot of two integers below 2**16 is the correctly rounded root of their exact sum of squares
         * (tests/native: every pair checked); the plan allows 16-bit integers only */
        if (has_speed)
            speed = sqrt(vx * vx + vy * vy) / 100;
        s->has_speed = (uint8_t)has_speed;
        s->speed = speed;
    } else {
        ms_val fx = ms_get(f, pm, MS_F_FIX_TYPE);
        if (!fx.has || fx.is_float)
            return 0;
        double usec;
        if (num(f, pm, MS_F_TIME_USEC, &usec) && usec >= (double)p->k[MS_K_UNIX_MIN_US] && fx.i >= p->k[MS_K_FIX_2D]) {
            int r = gps_time(a, s, sender, g, f, usec);
            if (r != 0)
                return r;
        }
        int r = fix(a, s, sender, g, f, t, fx.i, ms_get(f, pm, MS_F_SATELLITES_VISIBLE));
        if (r != 0)
            return r;
        if (fx.i < p->k[MS_K_FIX_2D]) {
            s->fixes[g].has = 0;
            return 0;
        }
        ms_val vel = ms_get(f, pm, MS_F_VEL);
        if (vel.has && !vel.is_float && vel.i != p->k[MS_K_UNKNOWN_VEL]) {
            has_speed = 1;
            speed = (double)vel.i / 100;
        } else {
            has_speed = s->has_speed;
            speed = s->speed;
        }
        ms_val h = ms_get(f, pm, MS_F_H_ACC);
        if (h.has && !h.is_float && 0 < h.i && h.i < 10000000)
            accuracy = (double)(3 * h.i) / 1000;
    }
    if (!has_lat || !has_lon)
        return 0;
    lat = lat / 1e7;
    lon = lon / 1e7;
    if (!(-90 <= lat && lat <= 90 && -180 <= lon && lon <= 180) ||
        (fabs(lat) < p->d[MS_D_NULL_ISLAND] && fabs(lon) < p->d[MS_D_NULL_ISLAND]))
        return 0;
    ms_fix prev = s->fixes[g];
    ms_fix *now = &s->fixes[g];
    now->has = 1;
    now->t = t;
    now->lat = lat;
    now->lon = lon;
    now->has_speed = (uint8_t)has_speed;
    now->speed = speed;
    now->record = f->record;
    if (!prev.has)
        return 0;
    double dt = t - prev.t;
    if (dt <= 0 || dt > p->d[MS_D_MAX_GAP_S] || !has_speed || !prev.has_speed)
        return 0;
    double d = distance_m(p, prev.lat, prev.lon, lat, lon);
    double v = prev.speed > speed ? prev.speed : speed; /* max(speed, prev.speed) */
    double allowed = p->d[MS_D_SPEED_FACTOR] * v * dt + 0.5 * p->d[MS_D_ACCEL_MPS2] * dt * dt + p->d[MS_D_MARGIN_M] +
                     accuracy;
    if (d >= p->d[MS_D_JUMP_MIN_M] && d > allowed) {
        NOTE(e, MS_GC_JUMP, d) {
            e->a[0] = d;
            e->a[1] = dt;
            e->a[2] = v;
            e->a[3] = allowed;
            e->n[0] = (int64_t)prev.record;
            e->n[1] = (int64_t)f->record;
        }
    }
    return 0;
}

static int system_time(ms_acc *a, ms_gsender *s, unsigned sender, int g, const ms_acc_frame *f,
                       const ms_plan_msg *pm) {
    double unix_us, boot;
    if (!num(f, pm, MS_F_TIME_UNIX_USEC, &unix_us) || !num(f, pm, MS_F_TIME_BOOT_MS, &boot) || unix_us == 0 ||
        boot == 0)
        return 0; /* no UTC yet; ground stations send boot 0 */
    double u = unix_us / 1e6, b = boot / 1000;
    int had = s->has_utc;
    double pu = s->utc_u, pb = s->utc_b, pt = s->utc_t;
    int p_has_t = s->utc_has_t;
    uint64_t precord = s->utc_record;
    s->has_utc = 1;
    s->utc_u = u;
    s->utc_b = b;
    s->utc_has_t = (uint8_t)f->has_time;
    s->utc_t = f->time;
    s->utc_record = f->record;
    if (!had || b < pb)
        return 0;
    double step = (u - b) - (pu - pb);
    if (fabs(step) > a->plan->d[MS_D_TIME_JUMP_S]) {
        NOTE(e, MS_GC_TIME, fabs(step)) {
            e->a[0] = step;
            e->n[0] = (int64_t)precord;
            e->n[1] = (int64_t)f->record;
            if (f->has_time && p_has_t) {
                e->flags |= 1;
                e->a[1] = (u - f->time) - (pu - pt);
            }
        }
    }
    return 0;
}

static int ekf(ms_acc *a, ms_gsender *s, unsigned sender, int g, const ms_acc_frame *f, const ms_plan_msg *pm) {
    const uint64_t *bits = g == MS_G_EKF ? a->plan->ekf_bits : a->plan->est_bits;
    const int ratios[2] = {g == MS_G_EKF ? MS_F_VELOCITY_VARIANCE : MS_F_VEL_RATIO,
                           g == MS_G_EKF ? MS_F_POS_HORIZ_VARIANCE : MS_F_POS_HORIZ_RATIO};
    const uint64_t healthy = bits[0], glitch = bits[1], pos_abs = bits[2], uninit = bits[3];
    ms_val fl = ms_get(f, pm, MS_F_FLAGS);
    if (!fl.has || fl.is_float || !healthy)
        return 0;
    const uint64_t flags = (uint64_t)fl.i;
    if (uninit && (flags & uninit)) { /* the filter starting over (a reboot, a reset): not an alarm */
        s->ekf_good = s->ekf_alarm = 0;
        return 0;
    }
    double worst = 0.0;
    int any = 0;
    for (int i = 0; i < 2; i++) {
        double v;
        if (num(f, pm, ratios[i], &v)) {
            if (!any || v > worst)
                worst = v;
            any = 1;
        }
    }
    int why = 0, nwhy = 0;
    if (glitch && (flags & glitch)) {
        why |= 1;
        nwhy++;
    }
    if (!(flags & pos_abs)) {
        why |= 2;
        nwhy++;
    }
    if (worst >= a->plan->d[MS_D_VARIANCE_ALARM]) {
        why |= 4;
        nwhy++;
    }
    if (!why && (flags & healthy) == healthy) {
        s->ekf_good = 1;
        s->ekf_alarm = 0;
        return 0;
    }
    if (s->ekf_good && why && !s->ekf_alarm) {
        s->ekf_alarm = 1;
        NOTE(e, MS_GC_EKF, worst + nwhy) {
            e->flags |= (uint8_t)why;
            e->a[0] = worst;
            e->n[0] = (int64_t)flags;
            e->n[1] = (int64_t)f->record;
        }
    }
    return 0;
}

int ms_gnss_add(ms_acc *a, const ms_acc_frame *f, const ms_plan_msg *pm) {
    const int g = kind_index(pm->kind);
    if (g < 0)
        return 0;
    const unsigned sender = (f->sysid << 8) | f->compid;
    uint32_t at;
    if (!ms_map_get(&a->gsender_index, sender, &at)) {
        if (a->gsenders.n >= (uint32_t)a->plan->k[MS_K_MAX_SENDERS])
            return 0;
        if (MS_VGROW(a, a->gsenders, (uint32_t)a->plan->k[MS_K_MAX_SENDERS]) != 0 ||
            ms_map_put(&a->gsender_index, sender, a->gsenders.n) != 0)
            return -1;
        at = a->gsenders.n++;
        memset(&a->gsenders.v[at], 0, sizeof a->gsenders.v[at]);
    }
    ms_gsender *s = &a->gsenders.v[at];
    if (!clock(a, s, g, f, pm))
        return 0;
    if (g <= MS_G_GPS2_RAW)
        return position(a, s, sender, g, f, pm);
    if (g == MS_G_SYSTEM_TIME)
        return system_time(a, s, sender, g, f, pm);
    return ekf(a, s, sender, g, f, pm);
}
