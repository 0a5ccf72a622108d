/* Live UDP capture in batches: datagrams taken from a socket with recvmmsg(2) (recvmsg(2) one at a time
 * where there is none), each written as a record of a nanosecond pcap (little-endian) holding the
 * Ethernet/IP/UDP packet mavscope/capture/synth.py `udp_packet` makes for it, byte for byte: the real
 * addresses and ports, IPv4 when both ends are IPv4 or IPv4-mapped, else IPv6.
 *
 * A batch of such records is what the live source queues (one queue item for many datagrams) and what
 * the native walker reads as the growing pcap of a live capture, so the records, their numbers and their
 * times are those the pure-Python receiver gives (mavscope/live/udp.py). No Python API here. */
#ifndef MAVSCOPE_NATIVE_RECV_H
#define MAVSCOPE_NATIVE_RECV_H

#include <stddef.h>
#include <stdint.h>

#include "buf.h"

#define MS_RECV_SLOTS 64           /* datagrams per recvmmsg call */
#define MS_RECV_SLOT_BYTES 65536   /* receive buffer per datagram: any UDP payload fits */

/* A packed address: 4 bytes (IPv4, or IPv6 mapping an IPv4 address) or 16. */
typedef struct {
    uint8_t len;
    uint8_t addr[16];
} ms_addr;

typedef struct {
    uint8_t *slots;          /* MS_RECV_SLOTS * MS_RECV_SLOT_BYTES */
    ms_addr local;           /* the bound address: the destination when the kernel gives no PKTINFO */
    uint16_t local_port;
    /* results of the last ms_recv_batch */
    uint64_t count;          /* datagrams received */
    uint64_t bytes;          /* their payload bytes */
    int64_t ovfl;            /* the latest SO_RXQ_OVFL counter seen, -1 when none came */
    uint64_t refused;        /* ECONNREFUSED returned (an ICMP error for an earlier send) */
    int err;                 /* errno of a failed receive other than EAGAIN/EINTR/ECONNREFUSED, or 0 */
} ms_receiver;

/* 0, or -1 when out of memory. */
int ms_receiver_init(ms_receiver *r, const ms_addr *local, uint16_t local_port);
void ms_receiver_free(ms_receiver *r);

/* Receive up to `max` datagrams already waiting on the non-blocking socket `fd`, appending one pcap
 * record per datagram to `out`; stops early when none is waiting. Results in r->count etc. Returns 0,
 * or -1 when `out` could not grow (out->failed) or the receive failed (r->err). */
int ms_recv_batch(ms_receiver *r, int fd, unsigned max, ms_buf *out);

/* One record: the pcap record header (sec, nsec, lengths) and the synthesised packet around `payload`.
 * 0, or -1 when the payload does not fit one IP packet (as udp_packet raises) or out of memory. */
int ms_udp_record(ms_buf *out, uint64_t sec, uint32_t nsec, const ms_addr *src, uint16_t sport,
                  const ms_addr *dst, uint16_t dport, const uint8_t *payload, size_t n);

/* The records of `in` (records as ms_udp_record writes them) with microsecond times, as the pure path's
 * pcap writer writes a record time t = sec + nsec / 1e9 (capture/writer.py _split_time: floor, then the
 * fraction rounded half to even), appended to `out`: the number of records, or -1 when `in` is not
 * whole records or `out` could not grow. */
long ms_records_to_micro(const uint8_t *in, size_t n, ms_buf *out);

/* The 24-byte global header of the pcap the records belong to (nanosecond, Ethernet, snaplen 262144). */
void ms_udp_pcap_header(uint8_t out[24]);

#endif
