/* Link, IP and UDP headers, as mavscope/transport/{link,ip}.py and Decapsulator._decode read them.
 *
 * ms_net_decode tells, for one packet record without reader notes, what the Python transport layer
 * would make of it: nothing at all (not IP, not UDP/TCP), one UDP payload with no note, or something
 * only Python handles (TCP with its reassembly state, malformed headers and fragments with their
 * notes, unknown link types): MS_NET_HANDBACK. */
#ifndef MAVSCOPE_NATIVE_NETLAYERS_H
#define MAVSCOPE_NATIVE_NETLAYERS_H

#include <stddef.h>
#include <stdint.h>

enum { MS_NET_SILENT = 0, MS_NET_UDP = 1, MS_NET_HANDBACK = 2 };

typedef struct {
    size_t start; /* payload: data[start .. start + len) */
    size_t len;
    int v6;
    uint8_t src[16], dst[16]; /* IPv4 uses the first 4 bytes */
    uint16_t sport, dport;
} ms_udp;

int ms_net_decode(int64_t linktype, const uint8_t *data, size_t n, ms_udp *out);

/* The ones' complement sum of p[0 .. n) as 16-bit big-endian words (a last odd byte padded with zero), added
 * to `acc` and left unfolded (at most 2**32 bytes' worth of words fit in 64 bits). */
static inline uint64_t ms_ones_sum(uint64_t acc, const uint8_t *p, size_t n) {
    size_t i = 0;
    for (; i + 1 < n; i += 2)
        acc += ((uint64_t)p[i] << 8) | p[i + 1];
    if (i < n)
        acc += (uint64_t)p[i] << 8;
    return acc;
}

/* "a.b.c.d:port" or "[v6]:port" as mavscope/transport/ip.py Endpoints names it; returns the length
 * (room for MS_ENDPOINT_MAX bytes). */
#define MS_ENDPOINT_MAX 64
int ms_fmt_endpoint(int v6, const uint8_t *addr, uint16_t port, char *out);

/* A UDP endpoint as the walker and the column mode remember it (addr: 4 bytes then zeros for IPv4). */
typedef struct {
    uint8_t v6;
    uint8_t addr[16];
    uint16_t port;
} ms_endpoint;

/* FNV-1a over an endpoint's fields, for the open-addressing tables that hold endpoints. */
static inline uint32_t ms_endpoint_hash(const ms_endpoint *e) {
    uint32_t h = 2166136261u;
    for (int i = 0; i < 16; i++)
        h = (h ^ e->addr[i]) * 16777619u;
    h = (h ^ e->port) * 16777619u;
    return (h ^ e->v6) * 16777619u;
}

#endif
