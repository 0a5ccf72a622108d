#include "plan.h"

#include <stdlib.h>
#include <string.h>

#include "blob.h"
#include "table.h"

/* bytes of one element of each MS_T_* type */
static const uint8_t TYPE_SIZE[] = {0, 1, 1, 2, 2, 4, 4, 8, 8, 4, 8, 1};

void ms_plan_free(ms_plan *p) {
    if (p->enums != NULL)
        for (uint32_t i = 0; i < p->n_ardupilot + MS_ENUM_FIXED; i++)
            free(p->enums[i].v);
    free(p->enums);
    free(p->msgs);
    free(p->slots);
    free(p->text);
    memset(p, 0, sizeof *p);
}

const ms_plan_entry *ms_plan_lookup(const ms_plan_enum *e, uint64_t value) {
    if (value > UINT32_MAX)
        return NULL;
    uint32_t lo = 0, hi = e->n;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (e->v[mid].value == value)
            return &e->v[mid];
        if (e->v[mid].value < value)
            lo = mid + 1;
        else
            hi = mid;
    }
    return NULL;
}

static int parse_enum(ms_cursor *c, ms_plan_enum *e, char *arena, size_t *used, size_t cap) {
    uint32_t n = (uint32_t)ms_take(c, 4);
    if (c->bad || n > (uint32_t)(c->end - c->p) / 5)
        return -1;
    e->v = calloc(n ? n : 1, sizeof *e->v);
    if (e->v == NULL)
        return -1;
    e->n = n;
    for (uint32_t i = 0; i < n; i++) {
        ms_plan_entry *en = &e->v[i];
        en->value = (uint32_t)ms_take(c, 4);
        en->len = (uint8_t)ms_take(c, 1);
        if (c->bad || (size_t)(c->end - c->p) < en->len || cap - *used < (size_t)en->len + 1)
            return -1;
        if (i > 0 && en->value <= e->v[i - 1].value)
            return -1;
        char *s = arena + *used;
        memcpy(s, c->p, en->len);
        s[en->len] = 0;
        for (size_t k = 0; k < en->len; k++)
            if ((unsigned char)s[k] < 0x20 || (unsigned char)s[k] > 0x7E) /* printable ASCII names only */
                return -1;
        *used += (size_t)en->len + 1;
        c->p += en->len;
        en->name = s;
    }
    return 0;
}

int ms_plan_parse(ms_plan *p, const uint8_t *blob, size_t len) {
    memset(p, 0, sizeof *p);
    ms_cursor c = {blob, blob + len, 0};
    if (len < 8 || memcmp(blob, "MSSP", 4) != 0)
        return -1;
    c.p += 4;
    if (ms_take(&c, 4) != 1)
        return -1;
    if (ms_take(&c, 2) != MS_K_COUNT)
        return -1;
    for (int i = 0; i < MS_K_COUNT; i++)
        p->k[i] = (int64_t)ms_take(&c, 8);
    if (ms_take(&c, 2) != MS_D_COUNT)
        return -1;
    for (int i = 0; i < MS_D_COUNT; i++) {
        uint64_t bits = ms_take(&c, 8);
        memcpy(&p->d[i], &bits, sizeof bits);
    }
    if (c.bad)
        return -1;
    /* the sizes the accumulator's fixed arrays assume (acc.h) */
    if (p->k[MS_K_GAPS_KEPT] < 0 || p->k[MS_K_GAPS_KEPT] > 127 || p->k[MS_K_LATE_WINDOW] != 128 ||
        p->k[MS_K_GAP_MIN] < 1 || p->k[MS_K_RESET_RUN] < 2 || p->k[MS_K_RESET_RUN] > 255 ||
        p->k[MS_K_MAX_CHANNELS] < 1 || p->k[MS_K_MAX_CHANNELS] > 64 || p->k[MS_K_MAX_EXTRA] < 0 ||
        p->k[MS_K_MAX_EXTRA] > (1 << 20) || p->k[MS_K_RATE_BINS] < 1 || p->k[MS_K_RATE_BINS] > 4096 ||
        p->k[MS_K_COPIES_KEPT] < 1 || p->k[MS_K_COPIES_KEPT] > (1 << 20) || p->k[MS_K_MAX_SENDERS] < 256 ||
        p->k[MS_K_MAX_SENDERS] > (1 << 16) || p->k[MS_K_MAX_FRAMES] < 1 || p->k[MS_K_MAX_FRAMES] > 64 ||
        p->k[MS_K_MAX_STREAMS] < 0 || p->k[MS_K_MAX_CONVERSATIONS] < 0 || p->k[MS_K_MAX_NAMED] < 0 ||
        p->k[MS_K_COMMANDERS_SHOWN] < 1 || p->k[MS_K_COMMANDERS_SHOWN] > MS_SHOWN_MAX || p->k[MS_K_RING] != MS_RING ||
        p->k[MS_K_MAX_EPISODES] < 0 || p->k[MS_K_MAX_EPISODES] > (1 << 20))
        return -1;
    uint32_t n = (uint32_t)ms_take(&c, 4);
    if (c.bad || n > 4096)
        return -1;
    p->msgs = calloc(n ? n : 1, sizeof *p->msgs);
    uint32_t nslots = 16;
    while (nslots < 2 * n)
        nslots *= 2;
    p->slots = malloc(nslots * sizeof *p->slots);
    size_t cap = len + 256, used = 0;
    p->text = malloc(cap);
    if (p->msgs == NULL || p->slots == NULL || p->text == NULL)
        goto fail;
    p->nslots = nslots;
    for (uint32_t i = 0; i < nslots; i++)
        p->slots[i] = -1;
    p->nmsgs = n;
    for (uint32_t m = 0; m < n; m++) {
        ms_plan_msg *pm = &p->msgs[m];
        pm->msgid = (uint32_t)ms_take(&c, 4);
        pm->kind = (uint8_t)ms_take(&c, 1);
        pm->roles = (uint8_t)ms_take(&c, 1);
        if (pm->msgid > 0xFFFFFF || pm->kind >= MS_M_COUNT || pm->roles > 15)
            goto fail;
        for (int s = 0; s < MS_NSLOTS; s++) {
            pm->slots[s].type = (uint8_t)ms_take(&c, 1);
            pm->slots[s].offset = (uint8_t)ms_take(&c, 1);
            unsigned t = pm->slots[s].type;
            if (t > MS_T_F64 || (t && (size_t)pm->slots[s].offset + TYPE_SIZE[t] > 255))
                goto fail; /* scalars only (native_stats.py checks each slot's type) */
        }
        if (c.bad)
            goto fail;
        uint32_t i = (pm->msgid * 2654435761u) & (nslots - 1);
        while (p->slots[i] >= 0) {
            if (p->msgs[p->slots[i]].msgid == pm->msgid)
                goto fail;
            i = (i + 1) & (nslots - 1);
        }
        p->slots[i] = (int32_t)m;
    }
    for (int i = 0; i < 32; i++)
        p->aerial[i] = (uint8_t)ms_take(&c, 1);
    for (int i = 0; i < 32; i++)
        p->gcs[i] = (uint8_t)ms_take(&c, 1);
    for (int i = 0; i < 32; i++)
        p->not_vehicles[i] = (uint8_t)ms_take(&c, 1);
    for (int i = 0; i < 256; i++)
        p->ardupilot[i] = (uint8_t)ms_take(&c, 1);
    uint32_t nenums = (uint32_t)ms_take(&c, 1);
    if (c.bad || nenums < MS_ENUM_FIXED)
        goto fail;
    p->n_ardupilot = nenums - MS_ENUM_FIXED;
    p->enums = calloc(nenums, sizeof *p->enums);
    if (p->enums == NULL)
        goto fail;
    for (uint32_t e = 0; e < nenums; e++)
        if (parse_enum(&c, &p->enums[e], p->text, &used, cap) != 0)
            goto fail;
    for (int i = 0; i < 256; i++)
        if (p->ardupilot[i] != 0xFF && p->ardupilot[i] >= p->n_ardupilot)
            goto fail;
    if (c.bad || (size_t)(c.end - c.p) < sizeof p->control_commands)
        goto fail;
    memcpy(p->control_commands, c.p, sizeof p->control_commands);
    c.p += sizeof p->control_commands;
    for (int i = 0; i < 4; i++)
        p->ekf_bits[i] = ms_take(&c, 8);
    for (int i = 0; i < 4; i++)
        p->est_bits[i] = ms_take(&c, 8);
    if (c.bad || c.p != c.end)
        goto fail;
    return 0;
fail:
    ms_plan_free(p);
    return -1;
}
