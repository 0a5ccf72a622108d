#define _POSIX_C_SOURCE 200809L /* inet_ntop */
#include "netlayers.h"

#include <arpa/inet.h>
#include <string.h>
#include <sys/socket.h>

#include "capture.h"
#include "fmt.h"

#define ETHERTYPE_IPV4 0x0800
#define ETHERTYPE_IPV6 0x86DD
#define MAX_EXT_HEADERS 16
#define FRAME_IP 1500 /* the IP packet one Ethernet frame holds (checksum.py FRAME_IP) */

/* strip_link: -1 unknown link type, -2 malformed, else the ethertype (0: not IP) and *off */
static int strip_link(int64_t lt, const uint8_t *d, size_t n, size_t *off) {
    switch (lt) {
    case 1: { /* Ethernet, 802.1Q / 802.1ad tags */
        if (n < 14)
            return -2;
        unsigned et = ms_be16(d + 12);
        size_t o = 14;
        while (et == 0x8100 || et == 0x88A8 || et == 0x9100) {
            if (o + 4 > n)
                return -2;
            et = ms_be16(d + o + 2);
            o += 4;
        }
        *off = o;
        return et < 0x0600 ? 0 : (int)et;
    }
    case 101: /* raw IP: the version nibble decides */
        *off = 0;
        if (n == 0)
            return 0;
        return (d[0] >> 4) == 4 ? ETHERTYPE_IPV4 : (d[0] >> 4) == 6 ? ETHERTYPE_IPV6 : 0;
    case 228:
        *off = 0;
        return ETHERTYPE_IPV4;
    case 229:
        *off = 0;
        return ETHERTYPE_IPV6;
    case 0:   /* BSD NULL: address family in host byte order */
    case 108: { /* OpenBSD LOOP: network byte order */
        if (n < 4)
            return -2;
        uint32_t af = lt == 0 ? ms_le32(d) : ms_be32(d);
        if (lt == 0 && af > 0xFFFF)
            af = ms_be32(d);
        *off = 4;
        if (af == 2)
            return ETHERTYPE_IPV4;
        if (af == 24 || af == 28 || af == 30)
            return ETHERTYPE_IPV6;
        return 0;
    }
    case 113: /* Linux SLL */
        if (n < 16)
            return -2;
        *off = 16;
        return ms_be16(d + 14);
    case 276: /* Linux SLL2 */
        if (n < 20)
            return -2;
        *off = 20;
        return ms_be16(d);
    default:
        return -1;
    }
}

static unsigned fold(uint64_t sum) {
    while (sum >> 16)
        sum = (sum & 0xFFFF) + (sum >> 16);
    return (unsigned)sum;
}

/* Whether the whole UDP datagram d[l4 .. l4 + ulen) has a checksum a receiver drops it for: wrong, and not
 * the pseudo-header sum a sender's kernel leaves for checksum offload; 0 over IPv6 (mavscope/transport/
 * checksum.py judge: Python notes it). */
static int udp_checksum_wrong(int v6, const uint8_t *src, const uint8_t *dst, const uint8_t *d, size_t l4,
                              size_t ulen) {
    unsigned field = ms_be16(d + l4 + 6);
    if (field == 0)
        return v6;
    size_t alen = v6 ? 16 : 4;
    uint64_t addresses = ms_ones_sum(ms_ones_sum(17, src, alen), dst, alen);
    unsigned pseudo = fold(addresses + ulen);
    if (fold(ms_ones_sum(pseudo, d + l4, ulen)) == 0xFFFF)
        return 0;
    return field != pseudo && field != fold(addresses); /* (the latter: the sum without the length, Windows' USO) */
}

int ms_net_decode(int64_t linktype, const uint8_t *d, size_t n, ms_udp *out) {
    size_t off = 0;
    int whole; /* the IP packet is all here, as long as its header says */
    int et = strip_link(linktype, d, n, &off);
    if (et < 0)
        return MS_NET_HANDBACK; /* an unknown link type is noted once; a malformed header always */
    unsigned proto;
    size_t l4, end;
    int v6;
    if (et == ETHERTYPE_IPV4) {
        if (off + 20 > n)
            return MS_NET_HANDBACK;
        const uint8_t *h = d + off;
        if ((h[0] >> 4) != 4)
            return MS_NET_HANDBACK;
        size_t ihl = (size_t)(h[0] & 15) * 4;
        if (ihl < 20 || off + ihl > n)
            return MS_NET_HANDBACK;
        size_t total = ms_be16(h + 2);
        /* (a record that reaches here is not snapped: a length past its end, or 0 in a packet one Ethernet frame
         * holds, is a header that lies, which Python notes: decap._length_lies) */
        if (total == 0 ? n - off <= FRAME_IP : total < ihl || off + total > n)
            return MS_NET_HANDBACK;
        end = total ? off + total : n;
        whole = total != 0;
        if (ms_be16(h + 6) & 0x3FFF)
            return MS_NET_HANDBACK; /* a fragment: noted */
        if (ihl > 20)
            return MS_NET_HANDBACK; /* options: Python judges them (ip.py options_problem) */
        if (ms_be16(h + 10) != 0 && fold(ms_ones_sum(0, h, 20)) != 0xFFFF)
            return MS_NET_HANDBACK; /* a wrong header checksum (0: left to the NIC): ip-bad-checksum */
        proto = h[9];
        memcpy(out->src, h + 12, 4);
        memcpy(out->dst, h + 16, 4);
        l4 = off + ihl;
        v6 = 0;
    } else if (et == ETHERTYPE_IPV6) {
        if (off + 40 > n)
            return MS_NET_HANDBACK;
        const uint8_t *h = d + off;
        if ((h[0] >> 4) != 6)
            return MS_NET_HANDBACK;
        size_t plen = ms_be16(h + 4);
        if (plen == 0 ? n - off <= FRAME_IP : off + 40 + plen > n)
            return MS_NET_HANDBACK; /* (as for IPv4 above) */
        end = plen ? off + 40 + plen : n;
        whole = plen != 0;
        unsigned nxt = h[6];
        size_t p = off + 40;
        int i;
        for (i = 0; i < MAX_EXT_HEADERS; i++) {
            if (nxt == 0 || nxt == 43 || nxt == 60) { /* hop-by-hop, routing, destination options */
                if (p + 8 > end)
                    return MS_NET_HANDBACK;
                nxt = d[p];
                p += ((size_t)d[p + 1] + 1) * 8;
            } else if (nxt == 44) { /* fragment header */
                if (p + 8 > end || plen == 0)
                    return MS_NET_HANDBACK; /* (in a jumbogram: Linux drops it, Python notes it) */
                if (ms_be16(d + p + 2) & 0xFFF9)
                    return MS_NET_HANDBACK; /* a fragment: noted */
                nxt = d[p];
                p += 8;
            } else {
                break;
            }
        }
        if (i == MAX_EXT_HEADERS || p > end)
            return MS_NET_HANDBACK;
        proto = nxt;
        memcpy(out->src, h + 8, 16);
        memcpy(out->dst, h + 24, 16);
        l4 = p;
        v6 = 1;
    } else {
        return MS_NET_SILENT; /* not IP */
    }
    if (proto == 6)
        return MS_NET_HANDBACK; /* TCP: reassembly state lives in Python */
    if (proto == 4 || proto == 41 || proto == 47)
        return MS_NET_HANDBACK; /* IP-in-IP, IPv6-in-IP, GRE: the tunnel's packet (mavscope/transport/tunnel.py) */
    if (proto != 17)
        return MS_NET_SILENT;
    if (l4 + 8 > end)
        return MS_NET_HANDBACK;
    size_t ulen = ms_be16(d + l4 + 4);
    if (ulen < 8) {
        if (ulen || !v6)
            return MS_NET_HANDBACK;
        ulen = end - l4; /* IPv6 jumbogram */
    }
    if (whole && (l4 + ulen > end || udp_checksum_wrong(v6, out->src, out->dst, d, l4, ulen)))
        return MS_NET_HANDBACK; /* a receiver drops it: Python notes why (decap._udp_dropped) */
    size_t stop = l4 + ulen < end ? l4 + ulen : end;
    out->start = l4 + 8;
    out->len = stop > l4 + 8 ? stop - (l4 + 8) : 0;
    out->v6 = v6;
    out->sport = ms_be16(d + l4);
    out->dport = ms_be16(d + l4 + 2);
    if (out->dport == 4789 || out->dport == 8472)
        return MS_NET_HANDBACK; /* VXLAN (tunnel.py VXLAN_PORTS): Python decodes what it carries */
    return MS_NET_UDP;
}

int ms_fmt_endpoint(int v6, const uint8_t *a, uint16_t port, char *out) {
    char *p = out;
    if (!v6) {
        for (int i = 0; i < 4; i++) {
            p = ms_w_u32(p, a[i]);
            *p++ = i < 3 ? '.' : ':';
        }
    } else {
        char text[INET6_ADDRSTRLEN];
        if (inet_ntop(AF_INET6, a, text, sizeof text) == NULL)
            text[0] = '\0';
        size_t k = strlen(text);
        *p++ = '[';
        memcpy(p, text, k);
        p += k;
        *p++ = ']';
        *p++ = ':';
    }
    p = ms_w_u32(p, port);
    return (int)(p - out);
}
