/* Batched live UDP receive (recv.h). The packet layout mirrors capture/synth.py udp_packet. */
#if defined(__linux__) && !defined(_GNU_SOURCE)
#define _GNU_SOURCE /* recvmmsg */
#endif
#include "recv.h"

#include "netlayers.h" /* ms_ones_sum */

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static const uint8_t ETH_V4[14] = {2, 0, 0, 0, 0, 2, 2, 0, 0, 0, 0, 1, 0x08, 0x00};
static const uint8_t ETH_V6[14] = {2, 0, 0, 0, 0, 2, 2, 0, 0, 0, 0, 1, 0x86, 0xdd};
static const uint8_t V4_MAPPED[12] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xff, 0xff};

static void put16(uint8_t *p, unsigned v) {
    p[0] = (uint8_t)(v >> 8);
    p[1] = (uint8_t)v;
}

static void put32le(uint8_t *p, uint32_t v) {
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

/* synth.internet_checksum: the folded sum is 0 only for all-zero data, as value % 0xFFFF there */
static unsigned fold(uint64_t acc) {
    while (acc >> 16)
        acc = (acc & 0xFFFF) + (acc >> 16);
    return (unsigned)(~acc & 0xFFFF);
}

void ms_udp_pcap_header(uint8_t out[24]) {
    memset(out, 0, 24);
    put32le(out, 0xA1B23C4Du);
    out[4] = 2; /* version 2.4 */
    out[6] = 4;
    put32le(out + 16, 262144u);
    put32le(out + 20, 1u); /* LINKTYPE_ETHERNET */
}

int ms_udp_record(ms_buf *out, uint64_t sec, uint32_t nsec, const ms_addr *src, uint16_t sport,
                  const ms_addr *dst, uint16_t dport, const uint8_t *payload, size_t n) {
    const int v4 = src->len == 4 && dst->len == 4;
    const size_t ulen = 8 + n;
    if (ulen > 0xFFFF || (v4 && 20 + ulen > 0xFFFF))
        return -1;
    const size_t head = 14 + (v4 ? 20 : 40) + 8;
    const size_t plen = head + n;
    uint8_t *p = (uint8_t *)ms_buf_room(out, 16 + plen);
    if (p == NULL)
        return -1;
    put32le(p, (uint32_t)sec);
    put32le(p + 4, nsec);
    put32le(p + 8, (uint32_t)plen);
    put32le(p + 12, (uint32_t)plen);
    uint8_t *q = p + 16;
    uint8_t *udp;
    uint64_t acc;
    if (v4) {
        memcpy(q, ETH_V4, 14);
        uint8_t *ip = q + 14;
        ip[0] = 0x45;
        ip[1] = 0;
        put16(ip + 2, (unsigned)(20 + ulen));
        put16(ip + 4, 0);
        put16(ip + 6, 0x4000);
        ip[8] = 64;
        ip[9] = 17;
        put16(ip + 10, 0);
        memcpy(ip + 12, src->addr, 4);
        memcpy(ip + 16, dst->addr, 4);
        put16(ip + 10, fold(ms_ones_sum(0, ip, 20)));
        udp = ip + 20;
        acc = ms_ones_sum(0, src->addr, 4);
        acc = ms_ones_sum(acc, dst->addr, 4);
    } else {
        uint8_t s16[16], d16[16];
        const ms_addr *a[2] = {src, dst};
        uint8_t *o[2] = {s16, d16};
        for (int k = 0; k < 2; k++) {
            if (a[k]->len == 16) {
                memcpy(o[k], a[k]->addr, 16);
            } else {
                memcpy(o[k], V4_MAPPED, 12);
                memcpy(o[k] + 12, a[k]->addr, 4);
            }
        }
        memcpy(q, ETH_V6, 14);
        uint8_t *ip = q + 14;
        ip[0] = 0x60;
        ip[1] = ip[2] = ip[3] = 0;
        put16(ip + 4, (unsigned)ulen);
        ip[6] = 17;
        ip[7] = 64;
        memcpy(ip + 8, s16, 16);
        memcpy(ip + 24, d16, 16);
        udp = ip + 40;
        acc = ms_ones_sum(0, s16, 16);
        acc = ms_ones_sum(acc, d16, 16);
    }
    acc += ulen + 17; /* the pseudo header's length and protocol (ulen < 2**16 either way) */
    put16(udp, sport);
    put16(udp + 2, dport);
    put16(udp + 4, (unsigned)ulen);
    put16(udp + 6, 0);
    acc = ms_ones_sum(acc, udp, 8);
    acc = ms_ones_sum(acc, payload, n);
    unsigned csum = fold(acc);
    put16(udp + 6, csum ? csum : 0xFFFF);
    if (n)
        memcpy(udp + 8, payload, n);
    out->len += 16 + plen;
    return 0;
}

static uint32_t get32le(const uint8_t *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

long ms_records_to_micro(const uint8_t *in, size_t n, ms_buf *out) {
    long count = 0;
    size_t pos = 0;
    while (pos < n) {
        if (n - pos < 16)
            return -1;
        const uint32_t sec = get32le(in + pos), nsec = get32le(in + pos + 4), incl = get32le(in + pos + 8);
        if (nsec >= 1000000000u || incl > n - pos - 16)
            return -1;
        const double t = (double)sec + (double)nsec / 1e9;
        double s = floor(t);
        double frac = nearbyint((t - s) * 1e6); /* Python's round(): half to even, the default mode */
        if (frac >= 1e6) {
            s += 1.0;
            frac -= 1e6;
        }
        if (s > 4294967295.0) { /* past the format's end (sec 2**32 - 1 and a rounding carry): its last tick */
            s = 4294967295.0;
            frac = 999999.0;
        }
        uint8_t *p = (uint8_t *)ms_buf_room(out, 16 + (size_t)incl);
        if (p == NULL)
            return -1;
        put32le(p, (uint32_t)s);
        put32le(p + 4, (uint32_t)frac);
        memcpy(p + 8, in + pos + 8, 8 + (size_t)incl);
        out->len += 16 + (size_t)incl;
        pos += 16 + (size_t)incl;
        count++;
    }
    return count;
}

#if defined(_WIN32)

int ms_receiver_init(ms_receiver *r, const ms_addr *local, uint16_t local_port) {
    memset(r, 0, sizeof *r);
    r->local = *local;
    r->local_port = local_port;
    return 0;
}

void ms_receiver_free(ms_receiver *r) { (void)r; }

int ms_recv_batch(ms_receiver *r, int fd, unsigned max, ms_buf *out) {
    (void)fd;
    (void)max;
    (void)out;
    r->count = r->bytes = r->refused = 0;
    r->ovfl = -1;
    r->err = ENOSYS;
    return -1;
}

#else

#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/uio.h>

#ifndef SO_TIMESTAMPNS
#define SO_TIMESTAMPNS 35
#endif
#ifndef SO_RXQ_OVFL
#define SO_RXQ_OVFL 40
#endif
#ifndef IP_PKTINFO
#define IP_PKTINFO 8
#endif
#ifndef IPV6_PKTINFO
#define IPV6_PKTINFO 50
#endif

#define CONTROL_BYTES 256 /* udp.py asks recvmsg for 256 bytes of ancillary data */

int ms_receiver_init(ms_receiver *r, const ms_addr *local, uint16_t local_port) {
    memset(r, 0, sizeof *r);
    r->local = *local;
    r->local_port = local_port;
    r->slots = malloc((size_t)MS_RECV_SLOTS * MS_RECV_SLOT_BYTES);
    return r->slots ? 0 : -1;
}

void ms_receiver_free(ms_receiver *r) {
    free(r->slots);
    r->slots = NULL;
}

/* udp.py _address: an IPv6 address mapping an IPv4 one is the IPv4 address; a scope id is not kept */
static void from_sockaddr(const struct sockaddr_storage *ss, ms_addr *a, uint16_t *port) {
    if (ss->ss_family == AF_INET) {
        const struct sockaddr_in *s = (const struct sockaddr_in *)ss;
        a->len = 4;
        memcpy(a->addr, &s->sin_addr, 4);
        *port = ntohs(s->sin_port);
    } else if (ss->ss_family == AF_INET6) {
        const struct sockaddr_in6 *s = (const struct sockaddr_in6 *)ss;
        const uint8_t *b = (const uint8_t *)&s->sin6_addr;
        if (memcmp(b, V4_MAPPED, 12) == 0) {
            a->len = 4;
            memcpy(a->addr, b + 12, 4);
        } else {
            a->len = 16;
            memcpy(a->addr, b, 16);
        }
        *port = ntohs(s->sin6_port);
    } else { /* not an IP socket: an unspecified IPv4 source */
        a->len = 4;
        memset(a->addr, 0, 4);
        *port = 0;
    }
}

/* One received datagram: its ancillary data, then its record. */
static int take(ms_receiver *r, struct msghdr *h, size_t len, ms_buf *out) {
    uint64_t sec = 0;
    uint32_t nsec = 0;
    int have_time = 0;
    ms_addr dst = r->local;
    for (struct cmsghdr *c = CMSG_FIRSTHDR(h); c != NULL; c = CMSG_NXTHDR(h, c)) {
        const uint8_t *cd = CMSG_DATA(c);
        const size_t clen = c->cmsg_len > CMSG_LEN(0) ? c->cmsg_len - CMSG_LEN(0) : 0;
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_TIMESTAMPNS && clen >= sizeof(struct timespec)) {
            struct timespec ts;
            memcpy(&ts, cd, sizeof ts);
            if (ts.tv_sec >= 0 && ts.tv_sec <= 0xFFFFFFFFll && ts.tv_nsec >= 0 && ts.tv_nsec < 1000000000l) {
                sec = (uint64_t)ts.tv_sec;
                nsec = (uint32_t)ts.tv_nsec;
                have_time = 1;
            }
        } else if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL && clen >= 4) {
            uint32_t v;
            memcpy(&v, cd, 4);
            r->ovfl = v;
        } else if (c->cmsg_level == IPPROTO_IP && c->cmsg_type == IP_PKTINFO && clen >= 12) {
            dst.len = 4;
            memcpy(dst.addr, cd + 8, 4); /* in_pktinfo.ipi_addr */
        } else if (c->cmsg_level == IPPROTO_IPV6 && c->cmsg_type == IPV6_PKTINFO && clen >= 16) {
            if (memcmp(cd, V4_MAPPED, 12) == 0) {
                dst.len = 4;
                memcpy(dst.addr, cd + 12, 4);
            } else {
                dst.len = 16;
                memcpy(dst.addr, cd, 16);
            }
        }
    }
    if (!have_time) { /* udp.py: time.time() at receipt */
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        sec = (uint64_t)ts.tv_sec;
        nsec = (uint32_t)ts.tv_nsec;
    }
    ms_addr src;
    uint16_t sport;
    from_sockaddr((const struct sockaddr_storage *)h->msg_name, &src, &sport);
    if (ms_udp_record(out, sec, nsec, &src, sport, &dst, r->local_port, (const uint8_t *)h->msg_iov->iov_base, len) != 0)
        return -1;
    r->count++;
    r->bytes += len;
    return 0;
}

int ms_recv_batch(ms_receiver *r, int fd, unsigned max, ms_buf *out) {
    r->count = r->bytes = r->refused = 0;
    r->ovfl = -1;
    r->err = 0;
    struct iovec iov[MS_RECV_SLOTS];
    struct sockaddr_storage names[MS_RECV_SLOTS];
    union {
        char buf[CONTROL_BYTES];
        struct cmsghdr align;
    } control[MS_RECV_SLOTS];
#if defined(__linux__)
    struct mmsghdr msgs[MS_RECV_SLOTS];
#else
    struct msghdr msgs[MS_RECV_SLOTS];
#endif
    while (r->count < max) {
        unsigned want = max - (unsigned)r->count < MS_RECV_SLOTS ? max - (unsigned)r->count : MS_RECV_SLOTS;
        for (unsigned i = 0; i < want; i++) {
            iov[i].iov_base = r->slots + (size_t)i * MS_RECV_SLOT_BYTES;
            iov[i].iov_len = MS_RECV_SLOT_BYTES;
#if defined(__linux__)
            struct msghdr *h = &msgs[i].msg_hdr;
#else
            struct msghdr *h = &msgs[i];
#endif
            memset(h, 0, sizeof *h);
            h->msg_name = &names[i];
            h->msg_namelen = sizeof names[i];
            h->msg_iov = &iov[i];
            h->msg_iovlen = 1;
            h->msg_control = control[i].buf;
            h->msg_controllen = CONTROL_BYTES;
        }
        int got;
#if defined(__linux__)
        got = recvmmsg(fd, msgs, want, MSG_DONTWAIT, NULL);
#else
        got = 0;
        for (unsigned i = 0; i < want; i++) {
            ssize_t k = recvmsg(fd, &msgs[i], MSG_DONTWAIT);
            if (k < 0) {
                if (got == 0)
                    got = -1;
                break;
            }
            iov[i].iov_len = (size_t)k; /* the length, as recvmmsg's msg_len */
            got++;
        }
#endif
        if (got < 0) {
            if (errno == EINTR)
                continue;
            if (errno == ECONNREFUSED) { /* udp.py: counted, and the receive goes on */
                r->refused++;
                continue;
            }
            if (errno == EAGAIN || errno == EWOULDBLOCK)
                return 0;
            r->err = errno;
            return -1;
        }
        for (int i = 0; i < got; i++) {
#if defined(__linux__)
            size_t len = msgs[i].msg_len;
            struct msghdr *h = &msgs[i].msg_hdr;
#else
            size_t len = iov[i].iov_len;
            struct msghdr *h = &msgs[i];
#endif
            if (take(r, h, len, out) != 0)
                return -1;
        }
        if ((unsigned)got < want)
            return 0; /* the socket is empty */
    }
    return 0;
}

#endif
