/* SHA-256 (FIPS 180-4), written from the standard for MAVLink 2 signatures (signing.h): a signature is
 * the first 6 bytes of SHA-256(secret || frame without its last 6 bytes).
 *
 * Incremental: ms_sha256_init, _update (any number of times), _final. A state is a plain value: copying
 * it (after hashing a key's secret) gives the start of every MAC of that key, as Python's
 * `hashlib.sha256(secret).copy()`. Checked against hashlib on random inputs and against the FIPS 180-2
 * appendix vectors (tests/native/test_signing_native.py). No input is read beyond `len` bytes. */
#ifndef MAVSCOPE_NATIVE_SHA256_H
#define MAVSCOPE_NATIVE_SHA256_H

#include <stddef.h>
#include <stdint.h>

#define MS_SHA256_LEN 32

typedef struct {
    uint32_t h[8];     /* the hash value H(i) */
    uint64_t bytes;    /* message length so far, in bytes */
    uint8_t block[64]; /* the message block being filled */
    size_t used;       /* bytes of `block` filled (0..63) */
} ms_sha256;

void ms_sha256_init(ms_sha256 *s);
void ms_sha256_update(ms_sha256 *s, const uint8_t *data, size_t len);
/* Pad, process the last block(s), write the 32-byte digest. The state is spent afterwards. */
void ms_sha256_final(ms_sha256 *s, uint8_t out[MS_SHA256_LEN]);

#endif
