/* Payload decoding straight to JSON text, from the layout table (table.h), as mavscope's
 * MessageDef.decode + orjson write it: the payload zero-padded to the message's full length, fields in
 * wire order, arrays as lists, char arrays as strings. */
#ifndef MAVSCOPE_NATIVE_DECODE_H
#define MAVSCOPE_NATIVE_DECODE_H

#include <stddef.h>
#include <stdint.h>

#include "table.h"

/* The "fields" object of a payload of `len` bytes (len <= 255) at p; room for m->json_max bytes. */
char *ms_w_fields(char *p, const ms_message *m, const uint8_t *payload, size_t len);

#define MS_SIGNATURE_JSON_MAX 160
/* The "signature" object of a signed frame no key checked (status no-key), from its 13-byte block. */
char *ms_w_signature_nokey(char *p, const uint8_t *block);

/* The most a `valid` signature object writes beyond the no-key one: the key's name (at most
 * MS_SIGN_NAME_MAX bytes of JSON) and the skew (a double, with its fixed-size copy). */
#define MS_SIGNATURE_VALID_EXTRA (64 + 256 + 48)
/* The "signature" object of a signed frame the walker judged valid (reason mac-ok): status `valid`, the
 * key's name (`key`, JSON text), and with a record time `t` the skew, round(signature time - t, 6). */
char *ms_w_signature_valid(char *p, const uint8_t *block, const char *key, size_t key_len, int has_time, double t);

/* "YYYY-MM-DDTHH:MM:SS" of a whole second since 2015-01-01T00:00:00Z (19 bytes, no NUL). */
void ms_iso_second(uint64_t seconds, char out[19]);

#endif
