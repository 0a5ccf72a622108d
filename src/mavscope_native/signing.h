/* MAVLink 2 signing state shared by the native walker and the Python SignatureVerifier
 * (mavscope/security/signing.py): the keys that have verified a stream, and per stream (sysid, compid,
 * link_id) the last accepted timestamp and the key that verified it last (the key tried first).
 *
 * One ms_signing lives in a `_native.SigningState`; the Python verifier stores its replay state there
 * (get/put between batches, while it judges handed-back frames), the walker reads and advances it for
 * the frames it judges itself (walk.c: a known stream, its key's MAC, a newer timestamp). Nothing here
 * decides anything else: new streams, replays and other keys are the Python verifier's.
 *
 * Keys: a slot per key, holding the SHA-256 state after its 32-byte secret (so a MAC costs the hashing
 * of the frame only) and its name as JSON text. A secret is never written anywhere, and wiped when the
 * state is freed. Streams: an open-addressing table over the 2^24 possible streams (16 bytes each), so
 * bounded by the stream space whatever the capture holds. */
#ifndef MAVSCOPE_NATIVE_SIGNING_H
#define MAVSCOPE_NATIVE_SIGNING_H

#include <stddef.h>
#include <stdint.h>

#include "sha256.h"

#define MS_SIGN_SECRET_LEN 32
#define MS_SIGN_NAME_MAX 256 /* longest key name (as JSON text) the walker writes; longer: Python does */
#define MS_SIGN_NO_KEY UINT32_MAX

typedef struct {
    ms_sha256 start; /* SHA-256 state after the secret */
    char *name;      /* the name as JSON text (quoted), or NULL: frames of this key are handed back */
    size_t name_len;
} ms_sign_key;

typedef struct {
    uint32_t stream; /* ms_sign_stream() + 1; 0: an empty slot */
    uint32_t key;    /* slot of the key that verified the stream last */
    uint64_t last;   /* last accepted timestamp (48 bits) */
} ms_sign_entry;

typedef struct {
    ms_sign_key *keys;
    size_t nkeys, capkeys;
    ms_sign_entry *slots;
    size_t nstreams, cap; /* cap: 0 or a power of two */
} ms_signing;

static inline uint32_t ms_sign_stream(unsigned sysid, unsigned compid, unsigned link_id) {
    return (uint32_t)(sysid & 0xFF) << 16 | (uint32_t)(compid & 0xFF) << 8 | (link_id & 0xFF);
}

void ms_signing_init(ms_signing *s);
/* Free everything, wiping the secrets' hash states first. */
void ms_signing_free(ms_signing *s);
/* A new key slot (its number, or -1 when out of memory). `name_json` may be NULL (never written natively). */
long ms_signing_add_key(ms_signing *s, const uint8_t secret[MS_SIGN_SECRET_LEN], const char *name_json,
                        size_t name_len);
/* The entry of `stream`, or NULL. */
const ms_sign_entry *ms_signing_find(const ms_signing *s, uint32_t stream);
/* Set a stream's last timestamp and key: 0, or -1 (out of memory, or no such key slot). */
int ms_signing_put(ms_signing *s, uint32_t stream, uint64_t last, uint32_t key);
/* Whether the first 6 bytes of SHA-256(secret || data[0..len)) equal mac[0..6) (compared in full,
 * without an early exit). */
int ms_signing_mac_ok(const ms_sign_key *k, const uint8_t *data, size_t len, const uint8_t mac[6]);

/* round(x, 6) as Python computes it (the decimal rounding of x's exact value to 6 places, ties to even,
 * read back as the nearest double). */
double ms_round6(double x);

#endif
