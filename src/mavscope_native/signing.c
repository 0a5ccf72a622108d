#include "signing.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void ms_signing_init(ms_signing *s) { memset(s, 0, sizeof *s); }

static void wipe(void *p, size_t n) {
    volatile unsigned char *v = p; /* not optimised away: the memory is freed right after */
    while (n--)
        *v++ = 0;
}

void ms_signing_free(ms_signing *s) {
    for (size_t i = 0; i < s->nkeys; i++)
        free(s->keys[i].name);
    if (s->keys != NULL)
        wipe(s->keys, s->capkeys * sizeof *s->keys);
    free(s->keys);
    free(s->slots);
    memset(s, 0, sizeof *s);
}

long ms_signing_add_key(ms_signing *s, const uint8_t secret[MS_SIGN_SECRET_LEN], const char *name_json,
                        size_t name_len) {
    if (s->nkeys >= MS_SIGN_NO_KEY - 1 || s->nkeys >= (size_t)LONG_MAX)
        return -1;
    if (s->nkeys == s->capkeys) {
        size_t cap = s->capkeys ? 2 * s->capkeys : 4;
        ms_sign_key *keys = calloc(cap, sizeof *keys);
        if (keys == NULL)
            return -1;
        if (s->nkeys) {
            memcpy(keys, s->keys, s->nkeys * sizeof *keys);
            wipe(s->keys, s->capkeys * sizeof *s->keys);
        }
        free(s->keys);
        s->keys = keys;
        s->capkeys = cap;
    }
    ms_sign_key *k = &s->keys[s->nkeys];
    k->name = NULL;
    k->name_len = 0;
    if (name_json != NULL && name_len <= MS_SIGN_NAME_MAX) {
        k->name = malloc(name_len ? name_len : 1);
        if (k->name == NULL)
            return -1;
        memcpy(k->name, name_json, name_len);
        k->name_len = name_len;
    }
    ms_sha256_init(&k->start);
    ms_sha256_update(&k->start, secret, MS_SIGN_SECRET_LEN);
    return (long)s->nkeys++;
}

static size_t slot_of(uint32_t stored, size_t cap) {
    return (size_t)((stored * 2654435761u) >> 8) & (cap - 1); /* Knuth's multiplicative hash */
}

const ms_sign_entry *ms_signing_find(const ms_signing *s, uint32_t stream) {
    if (s->cap == 0)
        return NULL;
    const uint32_t stored = stream + 1;
    for (size_t j = slot_of(stored, s->cap);; j = (j + 1) & (s->cap - 1)) {
        if (s->slots[j].stream == stored)
            return &s->slots[j];
        if (s->slots[j].stream == 0)
            return NULL; /* the load stays at most one half: an empty slot always ends the probe */
    }
}

int ms_signing_put(ms_signing *s, uint32_t stream, uint64_t last, uint32_t key) {
    if (key >= s->nkeys || stream > 0xFFFFFFu)
        return -1;
    ms_sign_entry *e = (ms_sign_entry *)ms_signing_find(s, stream);
    if (e != NULL) {
        e->last = last;
        e->key = key;
        return 0;
    }
    if (2 * (s->nstreams + 1) > s->cap) { /* at most 2^24 streams: the table stops at 2^25 slots */
        size_t cap = s->cap ? 2 * s->cap : 64;
        ms_sign_entry *slots = calloc(cap, sizeof *slots);
        if (slots == NULL)
            return -1;
        for (size_t i = 0; i < s->cap; i++) {
            if (s->slots[i].stream == 0)
                continue;
            size_t j = slot_of(s->slots[i].stream, cap);
            while (slots[j].stream != 0)
                j = (j + 1) & (cap - 1);
            slots[j] = s->slots[i];
        }
        free(s->slots);
        s->slots = slots;
        s->cap = cap;
    }
    const uint32_t stored = stream + 1;
    size_t j = slot_of(stored, s->cap);
    while (s->slots[j].stream != 0)
        j = (j + 1) & (s->cap - 1);
    s->slots[j].stream = stored;
    s->slots[j].key = key;
    s->slots[j].last = last;
    s->nstreams++;
    return 0;
}

int ms_signing_mac_ok(const ms_sign_key *k, const uint8_t *data, size_t len, const uint8_t mac[6]) {
    ms_sha256 h = k->start;
    uint8_t digest[MS_SHA256_LEN];
    ms_sha256_update(&h, data, len);
    ms_sha256_final(&h, digest);
    unsigned diff = 0;
    for (int i = 0; i < 6; i++)
        diff |= (unsigned)(digest[i] ^ mac[i]);
    wipe(&h, sizeof h);
    return diff == 0;
}

/* Python's round(x, 6): float_round with ndigits 6 rounds the exact binary value of x to 6 decimals
 * (dtoa mode 3, ties to even) and reads the decimal back (strtod: the nearest double). Here:
 * - |x| >= 2^33 (and NaN, infinities): x itself. Its neighbours are 2^-19 > 1.9e-6 away, the decimal
 *   within 5e-7 of it, so the nearest double to that decimal is x.
 * - else r = the integer nearest x * 10^6, from the double product when its fraction is clearly away from
 *   one half (the product's rounding error is below |y| * 2^-53; 4x that is the margin), else from the
 *   digits glibc's exact "%.6f" gives (ties to even, as dtoa); r < 2^53, and r / 10^6 in double is the
 *   nearest double to the decimal r * 10^-6 (one correctly rounded division of exact operands). A zero
 *   keeps x's sign ("-0" reads back as -0.0). */
double ms_round6(double x) {
    if (!(fabs(x) < 0x1p33))
        return x;
    const double y = x * 1e6;
    const double f = floor(y);
    const double frac = y - f;
    double r;
    if (fabs(frac - 0.5) > fabs(y) * 0x1p-51 + 0x1p-60) {
        r = frac < 0.5 ? f : f + 1.0;
    } else {
        char text[64];
        int n = snprintf(text, sizeof text, "%.6f", x);
        if (n <= 0 || (size_t)n >= sizeof text)
            return x; /* cannot happen for |x| < 2^33 */
        uint64_t v = 0;
        for (int i = 0; i < n; i++)
            if (text[i] >= '0' && text[i] <= '9')
                v = v * 10 + (uint64_t)(text[i] - '0'); /* below 2^33 * 10^6 < 2^53 */
        r = (double)v;
        if (x < 0)
            r = -r;
    }
    if (r == 0.0)
        return copysign(0.0, x);
    return r / 1e6;
}
