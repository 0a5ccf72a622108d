/* mavscope._native's live receive (recv.h), for mavscope/live/udp.py:
 *
 *   Receiver(local: bytes, local_port: int)   local: the bound address, packed (4 or 16 bytes)
 *     .receive(fd: int, max: int) -> tuple[bytes, int, int, int, int]
 *         (pcap records, datagrams, payload bytes, latest SO_RXQ_OVFL or -1, ECONNREFUSED count)
 *   udp_record(sec, nsec, src: bytes, sport, dst: bytes, dport, payload) -> bytes   (for the tests)
 *   records_to_micro(records) -> tuple[bytes, int]   the records with microsecond times, and how many
 *   UDP_PCAP_HEADER: bytes                     the global header of the records' pcap
 *
 * The receive runs without the GIL; the caller owns the socket and keeps it open while it runs. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "module_recv.h"
#include "recv.h"

typedef struct {
    PyObject_HEAD
    ms_receiver recv;
    ms_buf out;
    int ok;
    int busy;
} ReceiverObject;

static void Receiver_dealloc(ReceiverObject *self) {
    if (self->ok)
        ms_receiver_free(&self->recv);
    ms_buf_free(&self->out);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int packed(PyObject *obj, ms_addr *a) {
    Py_buffer b;
    if (PyObject_GetBuffer(obj, &b, PyBUF_SIMPLE) != 0)
        return -1;
    if (b.len != 4 && b.len != 16) {
        PyBuffer_Release(&b);
        PyErr_SetString(PyExc_ValueError, "a packed address has 4 or 16 bytes");
        return -1;
    }
    a->len = (uint8_t)b.len;
    memcpy(a->addr, b.buf, (size_t)b.len);
    PyBuffer_Release(&b);
    return 0;
}

static int Receiver_init(ReceiverObject *self, PyObject *args, PyObject *kwds) {
    static char *kwlist[] = {"local", "local_port", NULL};
    PyObject *local;
    int port;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "Oi", kwlist, &local, &port))
        return -1;
    ms_addr a;
    if (packed(local, &a) != 0)
        return -1;
    if (port < 0 || port > 0xFFFF) {
        PyErr_SetString(PyExc_ValueError, "local_port must be 0-65535");
        return -1;
    }
    if (self->ok) {
        PyErr_SetString(PyExc_RuntimeError, "Receiver already initialised");
        return -1;
    }
    if (ms_receiver_init(&self->recv, &a, (uint16_t)port) != 0) {
        PyErr_NoMemory();
        return -1;
    }
    ms_buf_init(&self->out);
    self->ok = 1;
    return 0;
}

static PyObject *Receiver_receive(ReceiverObject *self, PyObject *args) {
    int fd;
    unsigned int max;
    if (!PyArg_ParseTuple(args, "iI", &fd, &max))
        return NULL;
    if (!self->ok || self->busy) {
        PyErr_SetString(PyExc_RuntimeError, "Receiver not initialised, or receiving already");
        return NULL;
    }
    self->out.len = 0;
    self->out.failed = 0;
    int rc;
    self->busy = 1;
    Py_BEGIN_ALLOW_THREADS
    rc = ms_recv_batch(&self->recv, fd, max, &self->out);
    Py_END_ALLOW_THREADS
    self->busy = 0;
    const ms_receiver *r = &self->recv;
    if (rc != 0 && self->out.failed)
        return PyErr_NoMemory();
    if (rc != 0 && r->err == 0) { /* cannot happen for a UDP payload: udp_packet would raise too */
        PyErr_SetString(PyExc_ValueError, "a datagram does not fit one IP packet");
        return NULL;
    }
    if (rc != 0 && r->count == 0) {
        errno = r->err;
        return PyErr_SetFromErrno(PyExc_OSError);
    }
    /* datagrams taken before a failure are delivered; the failure comes back on the next call */
    PyObject *data = PyBytes_FromStringAndSize(self->out.data ? self->out.data : "", (Py_ssize_t)self->out.len);
    if (self->out.cap > (8u << 20))
        ms_buf_free(&self->out);
    if (data == NULL)
        return NULL;
    return Py_BuildValue("(NKKLK)", data, (unsigned long long)r->count, (unsigned long long)r->bytes,
                         (long long)r->ovfl, (unsigned long long)r->refused);
}

static PyMethodDef Receiver_methods[] = {
    {"receive", (PyCFunction)Receiver_receive, METH_VARARGS,
     "receive(fd, max): the datagrams waiting on the non-blocking socket fd (at most max) as pcap records; "
     "(records, datagrams, payload bytes, latest SO_RXQ_OVFL or -1, ECONNREFUSED count)"},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject ReceiverType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "mavscope._native.Receiver",
    .tp_basicsize = sizeof(ReceiverObject),
    .tp_dealloc = (destructor)Receiver_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Batched UDP receive for live capture (mavscope.live.udp).",
    .tp_methods = Receiver_methods,
    .tp_init = (initproc)Receiver_init,
    .tp_new = PyType_GenericNew,
};

PyObject *ms_py_udp_record(PyObject *Py_UNUSED(mod), PyObject *args) {
    unsigned long long sec;
    unsigned int nsec;
    PyObject *src, *dst;
    int sport, dport;
    Py_buffer payload;
    if (!PyArg_ParseTuple(args, "KIOiOiy*", &sec, &nsec, &src, &sport, &dst, &dport, &payload))
        return NULL;
    ms_addr s, d;
    PyObject *res = NULL;
    if (packed(src, &s) == 0 && packed(dst, &d) == 0) {
        if (sport < 0 || sport > 0xFFFF || dport < 0 || dport > 0xFFFF || nsec >= 1000000000u || sec > 0xFFFFFFFFull) {
            PyErr_SetString(PyExc_ValueError, "port, nsec or sec out of range");
        } else {
            ms_buf out;
            ms_buf_init(&out);
            if (ms_udp_record(&out, sec, nsec, &s, (uint16_t)sport, &d, (uint16_t)dport, (const uint8_t *)payload.buf,
                              (size_t)payload.len) != 0)
                PyErr_SetString(PyExc_ValueError, "the payload does not fit one IP packet");
            else
                res = PyBytes_FromStringAndSize(out.data, (Py_ssize_t)out.len);
            ms_buf_free(&out);
        }
    }
    PyBuffer_Release(&payload);
    return res;
}

PyObject *ms_py_records_to_micro(PyObject *Py_UNUSED(mod), PyObject *arg) {
    Py_buffer b;
    if (PyObject_GetBuffer(arg, &b, PyBUF_SIMPLE) != 0)
        return NULL;
    ms_buf out;
    ms_buf_init(&out);
    long count = ms_records_to_micro((const uint8_t *)b.buf, (size_t)b.len, &out);
    PyBuffer_Release(&b);
    PyObject *res = NULL;
    if (out.failed)
        PyErr_NoMemory();
    else if (count < 0)
        PyErr_SetString(PyExc_ValueError, "not whole records of a live capture's batch");
    else
        res = Py_BuildValue("(y#l)", out.data ? out.data : "", (Py_ssize_t)out.len, count);
    ms_buf_free(&out);
    return res;
}

int ms_py_add_receiver(PyObject *m) {
    if (PyType_Ready(&ReceiverType) < 0)
        return -1;
    uint8_t header[24];
    ms_udp_pcap_header(header);
    Py_INCREF(&ReceiverType);
    if (PyModule_AddObject(m, "Receiver", (PyObject *)&ReceiverType) < 0) {
        Py_DECREF(&ReceiverType);
        return -1;
    }
    PyObject *h = PyBytes_FromStringAndSize((const char *)header, 24);
    if (h == NULL || PyModule_AddObject(m, "UDP_PCAP_HEADER", h) < 0) {
        Py_XDECREF(h);
        return -1;
    }
    return 0;
}
