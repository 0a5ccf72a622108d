/* Payload decoding straight to JSON text, from the layout table (table.h), as mavscope's
 * MessageDef.decode + orjson write it: the payload zero-padded to the message's full length, fields in
 * wire order, arrays as lists, char arrays as strings. */
#ifndef MAVSCOPE_NATIVE_DECODE_H
#define MAVSCOPE_NATIVE_DECODE_H

#include <stddef.h>
#include <stdint.h>

#include "buf.h"
#include "table.h"

/* The "fields" object of a payload of `len` bytes (len <= 255). */
void ms_put_fields(ms_buf *b, const ms_message *m, const uint8_t *payload, size_t len);

/* The "signature" object of a signed frame that no key checked (status no-key), from the 13-byte block. */
void ms_put_signature_nokey(ms_buf *b, const uint8_t *block);

/* "YYYY-MM-DDTHH:MM:SS" of a whole second since 2015-01-01T00:00:00Z (19 bytes, no NUL). */
void ms_iso_second(uint64_t seconds, char out[19]);

#endif
