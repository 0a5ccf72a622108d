/* mavscope._native: the CPython face of the native core (see mavscope/native/ for the Python side).
 *
 *   Table(blob: bytes)                  the message layouts, compiled by mavscope.native from a Dialect
 *   Summary(table, blob: bytes)         what summary lines show per message (mavscope.native_summary)
 *   Walker(fd: int, size: int, kind: int, table, endpoints: set, endpoint: Callable[[bytes, int], object],
 *          signed_senders: set[tuple[int, int]], window: int = 1 << 20, summary: Summary | None = None,
 *          t0: float | None = None, columns: Columns | None = None,
 *          receivers: dict | None = None, notes=None, ports=None, raw: RawLink | None = None)
 *                                        with `raw` (kind raw; the Dissector's RawLink): the raw stream's
 *                                        clean stretches are written (or put into `columns`), pieces around
 *                                        damage handed back (walk.c walk_raw); its `frames` and `held` read
 *                                        per `next`, `frames` set after it
 *                                        with `receivers` (the Dissector's: UDP port -> receivers): a datagram
 *                                        to one of its ports is handed back (read after each record
 *                                        handed back, the only thing that changes it); every record while
 *                                        its `hand_back` (a dict subclass's attribute, read per `next`) is
 *                                        true (a TCP hole waits, which any record's time may end)
 *                                        with `summary`: summary lines (relative to t0) instead of JSON;
 *     .next(signed_nokey: bool, limit: int = 1 << 20, into: bytearray | None = None,
 *           signing: SigningState | None = None) -> list[bytes | bytearray | tuple] | None
 *         with `signing` (and not signed_nokey): signed frames of known streams judged against it
 *     .walked() -> tuple[int, float | None, int | None] | None
 *     .stats() -> dict[str, int]
 *     .close()
 *     .feed(records)                    with fd=-1 (and size 0, kind pcap): a pcap that grows, fed whole
 *                                        records (live capture: the global header, then Receiver batches)
 *   SigningState()                       the signing state both paths share (signing.h): key slots,
 *     .add_key(secret: bytes, name: str) -> int       per stream the last accepted timestamp and key
 *     .get(stream: tuple[int, int, int]) -> tuple[int, int] | None     (last, key slot)
 *     .put(stream, last: int, key: int), len()
 *   sha256(data) -> bytes, format_skew(x) -> bytes   (the signing code, for the tests)
 *   Receiver, udp_record, UDP_PCAP_HEADER (module_recv.c: live capture's batched receive)
 *   join_fields(columns, separator, quote) -> str   (module_fields.c: read -T fields' lines)
 *   Columns(table, limit: int = 65536, *, index: bool = False, notes: bool = False)  column mode (columns.h):
 *       Walker(..., columns=Columns); `index`: only the columns the TUI's index takes; `notes`: frames with
 *       the notes of NOTE_* are taken, their code in the `note` column; `.limit` settable
 *     fills it instead of writing JSON Lines, stopping once it holds `limit` frames
 *     .frames -> int                     frames held
 *     .take() -> (frames, endpoints_reset, new_endpoints, columns, messages)   the chunk, whose memory
 *         passes to Python as read-only Block objects (the buffer protocol): columns, one per MS_COL_*;
 *         messages, (position in the table, rows, frame positions, count) per message with rows;
 *         new_endpoints, (packed address, port) of the endpoint ids first used in this chunk, in id order
 *   COLUMN_NAMES: tuple[str, ...]       the names of those columns, in order
 *   KIND_*: the capture kinds a Walker takes (capture.h MS_KIND_*); COLUMN_TRANSPORT_*: the codes of the
 *       transport column (columns.h MS_TRANSPORT_*); NOTE_*: the bits of the note column (MS_NOTE_*).
 *       Python reads them from here only (mavscope/native/core.py; the typed contract: mavscope/_native.pyi)
 *   format_double(x) -> bytes, text_json(b) -> bytes   (the JSON formatting, for the tests)
 *   format_f32(x, repr), format_double_repr(x), format_degrees(v, unsigned), format_reltime(t), repr_ascii(b) -> bytes | None
 *                                        (the summary formatting, for the tests)
 *
 * The walker reads the file with pread(2) on `fd` (never a memory mapping: a file truncated while it is
 * read ends with a note, see capture.h); the caller owns the descriptor and keeps it open while the
 * walker lives. The walk itself runs without the GIL; the two Python sets are read before and updated
 * after it (a new source of valid MAVLink goes into `endpoints` as endpoint(packed address, port)). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "buf.h"
#include "capture.h"
#include "columns.h"
#include "fmt.h"
#include "module_fields.h"
#include "module_recv.h"
#include "netlayers.h"
#include "sha256.h"
#include "signing.h"
#include "summary.h"
#include "table.h"
#include "walk.h"

/* ---- Table -------------------------------------------------------------------------------- */

typedef struct {
    PyObject_HEAD
    ms_table table;
    int ok;
} TableObject;

static void Table_dealloc(TableObject *self) {
    ms_table_free(&self->table);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int Table_init(TableObject *self, PyObject *args, PyObject *kwds) {
    static char *kwlist[] = {"blob", NULL};
    Py_buffer blob;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "y*", kwlist, &blob))
        return -1;
    if (self->ok) {
        ms_table_free(&self->table);
        self->ok = 0;
    }
    int r = ms_table_parse(&self->table, (const uint8_t *)blob.buf, (size_t)blob.len);
    PyBuffer_Release(&blob);
    if (r != 0) {
        PyErr_SetString(PyExc_ValueError, "malformed message table");
        return -1;
    }
    self->ok = 1;
    return 0;
}

static PyObject *Table_len(TableObject *self, PyObject *Py_UNUSED(ignored)) {
    return PyLong_FromSize_t(self->table.count);
}

static PyMethodDef Table_methods[] = {
    {"count", (PyCFunction)Table_len, METH_NOARGS, "number of messages in the table"},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject TableType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "mavscope._native.Table",
    .tp_basicsize = sizeof(TableObject),
    .tp_dealloc = (destructor)Table_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Message layouts for the native walker (built by mavscope.native.build_table).",
    .tp_methods = Table_methods,
    .tp_init = (initproc)Table_init,
    .tp_new = PyType_GenericNew,
};

/* ---- Summary ------------------------------------------------------------------------------ */

typedef struct {
    PyObject_HEAD
    ms_summary summary;
    PyObject *table; /* TableObject: the summary points into its messages */
    int ok;
} SummaryObject;

static void Summary_dealloc(SummaryObject *self) {
    if (self->ok)
        ms_summary_free(&self->summary);
    Py_XDECREF(self->table);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int Summary_init(SummaryObject *self, PyObject *args, PyObject *kwds) {
    static char *kwlist[] = {"table", "blob", NULL};
    PyObject *table;
    Py_buffer blob;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "O!y*", kwlist, &TableType, &table, &blob))
        return -1;
    if (self->ok) {
        PyBuffer_Release(&blob);
        PyErr_SetString(PyExc_RuntimeError, "Summary already initialised");
        return -1;
    }
    int r = ms_summary_parse(&self->summary, &((TableObject *)table)->table, (const uint8_t *)blob.buf,
                             (size_t)blob.len);
    PyBuffer_Release(&blob);
    if (r != 0) {
        PyErr_SetString(PyExc_ValueError, "malformed summary table");
        return -1;
    }
    Py_INCREF(table);
    self->table = table;
    self->ok = 1;
    return 0;
}

static PyTypeObject SummaryType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "mavscope._native.Summary",
    .tp_basicsize = sizeof(SummaryObject),
    .tp_dealloc = (destructor)Summary_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "What summary lines show per message (built by mavscope.native_summary).",
    .tp_init = (initproc)Summary_init,
    .tp_new = PyType_GenericNew,
};

/* ---- Block, Columns (the export's column mode) -------------------------------------------- */

/* Memory the column buffers grew in C, handed to Python without a copy (read-only buffer protocol). */
typedef struct {
    PyObject_HEAD
    char *data;
    Py_ssize_t len;
} BlockObject;

static void Block_dealloc(BlockObject *self) {
    free(self->data);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int Block_getbuffer(BlockObject *self, Py_buffer *view, int flags) {
    return PyBuffer_FillInfo(view, (PyObject *)self, self->data ? self->data : (char *)"", self->len, 1, flags);
}

static Py_ssize_t Block_length(BlockObject *self) {
    return self->len;
}

static PyBufferProcs Block_as_buffer = {(getbufferproc)Block_getbuffer, NULL};
static PySequenceMethods Block_as_sequence = {.sq_length = (lenfunc)Block_length};

static PyTypeObject BlockType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "mavscope._native.Block",
    .tp_basicsize = sizeof(BlockObject),
    .tp_dealloc = (destructor)Block_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Read-only bytes of a column chunk, owned by Python once taken (buffer protocol).",
    .tp_as_buffer = &Block_as_buffer,
    .tp_as_sequence = &Block_as_sequence,
};

/* A Block taking the memory of `b` (which is left empty). */
static PyObject *block_from(ms_buf *b) {
    BlockObject *o = PyObject_New(BlockObject, &BlockType);
    if (o == NULL)
        return NULL;
    o->data = b->data;
    o->len = (Py_ssize_t)b->len;
    ms_buf_init(b);
    return (PyObject *)o;
}

typedef struct {
    PyObject_HEAD
    ms_cols cols;
    PyObject *table; /* TableObject: the columns point into its messages */
    int ok;
    int busy;        /* a Walker is filling it (without the GIL) */
} ColumnsObject;

static void Columns_dealloc(ColumnsObject *self) {
    if (self->ok)
        ms_cols_free(&self->cols);
    Py_XDECREF(self->table);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int Columns_init(ColumnsObject *self, PyObject *args, PyObject *kwds) {
    static char *kwlist[] = {"table", "limit", "index", "notes", NULL};
    PyObject *table;
    Py_ssize_t limit = 65536;
    int index_only = 0, notes = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "O!|n$pp", kwlist, &TableType, &table, &limit, &index_only,
                                     &notes))
        return -1;
    if (index_only && notes) {
        PyErr_SetString(PyExc_ValueError, "an index chunk carries no notes");
        return -1;
    }
    if (self->ok) {
        PyErr_SetString(PyExc_RuntimeError, "Columns already initialised");
        return -1;
    }
    if (limit < 1 || limit > (Py_ssize_t)MS_COLS_MAX_FRAMES) {
        PyErr_SetString(PyExc_ValueError, "limit out of range");
        return -1;
    }
    if (ms_cols_init(&self->cols, &((TableObject *)table)->table, (uint32_t)limit) != 0) {
        PyErr_NoMemory();
        return -1;
    }
    self->cols.index_only = index_only;
    self->cols.notes = notes;
    Py_INCREF(table);
    self->table = table;
    self->ok = 1;
    return 0;
}

/* limit = n: the frames a chunk holds from now on (the TUI's index takes a small first chunk). */
static int Columns_set_limit(ColumnsObject *self, PyObject *value, void *Py_UNUSED(closure)) {
    Py_ssize_t limit = value == NULL ? -1 : PyLong_AsSsize_t(value);
    if (limit == -1 && PyErr_Occurred())
        return -1;
    if (!self->ok || self->busy || limit < 1 || limit > (Py_ssize_t)MS_COLS_MAX_FRAMES) {
        PyErr_SetString(PyExc_ValueError, "limit out of range (or Columns busy)");
        return -1;
    }
    self->cols.limit = (uint32_t)limit;
    return 0;
}

static PyObject *Columns_limit(ColumnsObject *self, void *Py_UNUSED(closure)) {
    return PyLong_FromUnsignedLong(self->ok ? self->cols.limit : 0);
}

static PyObject *Columns_frames(ColumnsObject *self, void *Py_UNUSED(closure)) {
    return PyLong_FromUnsignedLong(self->ok ? self->cols.n : 0);
}

static PyObject *Columns_take(ColumnsObject *self, PyObject *Py_UNUSED(ignored)) {
    if (!self->ok) {
        PyErr_SetString(PyExc_RuntimeError, "Columns not initialised");
        return NULL;
    }
    if (self->busy) {
        PyErr_SetString(PyExc_RuntimeError, "a Walker is filling these Columns");
        return NULL;
    }
    ms_cols *c = &self->cols;
    if (c->failed)
        return PyErr_NoMemory();
    PyObject *ends = NULL, *cols = NULL, *msgs = NULL, *res = NULL;
    ends = PyList_New(0);
    cols = PyList_New(MS_NCOLS);
    msgs = PyList_New(0);
    if (ends == NULL || cols == NULL || msgs == NULL)
        goto done;
    for (uint32_t i = c->first_new; i < c->nends; i++) {
        const ms_endpoint *e = &c->ends[i];
        PyObject *t = Py_BuildValue("(y#i)", (const char *)e->addr, (Py_ssize_t)(e->v6 ? 16 : 4), (int)e->port);
        if (t == NULL || PyList_Append(ends, t) != 0) {
            Py_XDECREF(t);
            goto done;
        }
        Py_DECREF(t);
    }
    for (int k = 0; k < MS_NCOLS; k++) {
        PyObject *b = block_from(&c->col[k]);
        if (b == NULL)
            goto done;
        PyList_SET_ITEM(cols, k, b);
    }
    for (uint32_t i = 0; i < c->ntouched; i++) {
        ms_msg_rows *r = &c->msgs[c->touched[i]];
        PyObject *rows = block_from(&r->rows);
        if (rows == NULL)
            goto done;
        PyObject *frame = block_from(&r->frame);
        if (frame == NULL) {
            Py_DECREF(rows);
            goto done;
        }
        PyObject *t = Py_BuildValue("(INNI)", c->touched[i], rows, frame, r->n); /* N: released on failure too */
        if (t == NULL)
            goto done;
        if (PyList_Append(msgs, t) != 0) {
            Py_DECREF(t);
            goto done;
        }
        Py_DECREF(t);
    }
    res = Py_BuildValue("(IOOOO)", c->n, c->reset ? Py_True : Py_False, ends, cols, msgs);
done:
    Py_XDECREF(ends);
    Py_XDECREF(cols);
    Py_XDECREF(msgs);
    ms_cols_restart(c); /* whatever was handed over; a failure above loses the chunk and raises */
    return res;
}

static PyMethodDef Columns_methods[] = {
    {"take", (PyCFunction)Columns_take, METH_NOARGS,
     "take() -> (frames, endpoints_reset, new_endpoints, columns, messages): the chunk held, as Blocks"},
    {NULL, NULL, 0, NULL},
};

static PyGetSetDef Columns_getset[] = {
    {"frames", (getter)Columns_frames, NULL, "frames held", NULL},
    {"limit", (getter)Columns_limit, (setter)Columns_set_limit, "frames a chunk holds", NULL},
    {NULL, NULL, NULL, NULL, NULL},
};

static PyTypeObject ColumnsType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "mavscope._native.Columns",
    .tp_basicsize = sizeof(ColumnsObject),
    .tp_dealloc = (destructor)Columns_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Column buffers a Walker fills in column mode (mavscope.export.native).",
    .tp_methods = Columns_methods,
    .tp_getset = Columns_getset,
    .tp_init = (initproc)Columns_init,
    .tp_new = PyType_GenericNew,
};

/* ---- SigningState ------------------------------------------------------------------------- */

/* Holds secrets (as SHA-256 states): nothing of them is readable from Python, printed or pickled. */
typedef struct {
    PyObject_HEAD
    ms_signing state;
    int busy; /* a walk uses it without the GIL: Python may not change it meanwhile */
} SigningObject;

static void Signing_dealloc(SigningObject *self) {
    ms_signing_free(&self->state);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int Signing_init(SigningObject *self, PyObject *args, PyObject *kwds) {
    static char *kwlist[] = {NULL};
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "", kwlist))
        return -1;
    if (self->busy) {
        PyErr_SetString(PyExc_RuntimeError, "SigningState is in use by a walk");
        return -1;
    }
    ms_signing_free(&self->state);
    ms_signing_init(&self->state);
    return 0;
}

static int signing_free_to_change(SigningObject *self) {
    if (self->busy) {
        PyErr_SetString(PyExc_RuntimeError, "SigningState is in use by a walk");
        return -1;
    }
    return 0;
}

static int parse_stream(PyObject *stream, uint32_t *out) {
    int sysid, compid, link;
    if (!PyArg_ParseTuple(stream, "iii", &sysid, &compid, &link))
        return -1;
    if (sysid < 0 || sysid > 255 || compid < 0 || compid > 255 || link < 0 || link > 255) {
        PyErr_SetString(PyExc_ValueError, "a stream is (sysid, compid, link_id), each 0..255");
        return -1;
    }
    *out = ms_sign_stream((unsigned)sysid, (unsigned)compid, (unsigned)link);
    return 0;
}

static PyObject *Signing_add_key(SigningObject *self, PyObject *args) {
    Py_buffer secret;
    PyObject *name;
    if (!PyArg_ParseTuple(args, "y*U", &secret, &name))
        return NULL;
    if (signing_free_to_change(self) != 0 || secret.len != MS_SIGN_SECRET_LEN) {
        if (!PyErr_Occurred()) /* the length only: never anything of the secret */
            PyErr_SetString(PyExc_ValueError, "a signing secret is 32 bytes");
        PyBuffer_Release(&secret);
        return NULL;
    }
    Py_ssize_t n = 0;
    const char *utf8 = PyUnicode_AsUTF8AndSize(name, &n);
    char *json = NULL;
    size_t json_len = 0;
    if (utf8 == NULL) {
        PyErr_Clear(); /* a name that is not UTF-8 (a lone surrogate): its frames are written by Python */
    } else if ((size_t)n <= MS_SIGN_NAME_MAX) {
        json = PyMem_Malloc(ms_text_max((size_t)n));
        if (json == NULL) {
            PyBuffer_Release(&secret);
            return PyErr_NoMemory();
        }
        json_len = (size_t)(ms_w_text(json, (const uint8_t *)utf8, (size_t)n) - json);
    }
    long slot = ms_signing_add_key(&self->state, (const uint8_t *)secret.buf, json, json_len);
    PyBuffer_Release(&secret);
    PyMem_Free(json);
    if (slot < 0)
        return PyErr_NoMemory();
    return PyLong_FromLong(slot);
}

static PyObject *Signing_get(SigningObject *self, PyObject *stream) {
    uint32_t st;
    if (parse_stream(stream, &st) != 0)
        return NULL;
    const ms_sign_entry *e = ms_signing_find(&self->state, st);
    if (e == NULL)
        Py_RETURN_NONE;
    return Py_BuildValue("(KI)", (unsigned long long)e->last, (unsigned int)e->key);
}

static PyObject *Signing_put(SigningObject *self, PyObject *args) {
    PyObject *stream, *last_obj;
    unsigned long key;
    if (!PyArg_ParseTuple(args, "OOk", &stream, &last_obj, &key))
        return NULL;
    uint32_t st;
    if (signing_free_to_change(self) != 0 || parse_stream(stream, &st) != 0)
        return NULL;
    unsigned long long last = PyLong_AsUnsignedLongLong(last_obj);
    if (last == (unsigned long long)-1 && PyErr_Occurred())
        return NULL;
    if (key >= self->state.nkeys) {
        PyErr_SetString(PyExc_ValueError, "no such key slot");
        return NULL;
    }
    if (ms_signing_put(&self->state, st, (uint64_t)last, (uint32_t)key) != 0)
        return PyErr_NoMemory();
    Py_RETURN_NONE;
}

static Py_ssize_t Signing_len(SigningObject *self) { return (Py_ssize_t)self->state.nstreams; }

static PyObject *Signing_repr(SigningObject *self) {
    return PyUnicode_FromFormat("SigningState(%zu keys, %zu streams)", self->state.nkeys, self->state.nstreams);
}

static PyObject *Signing_reduce(SigningObject *Py_UNUSED(self), PyObject *Py_UNUSED(ignored)) {
    PyErr_SetString(PyExc_TypeError, "a SigningState holds keys: it is not copied or pickled");
    return NULL;
}

static PyMethodDef Signing_methods[] = {
    {"add_key", (PyCFunction)Signing_add_key, METH_VARARGS,
     "add_key(secret: bytes, name: str) -> int: a new key slot (32-byte secret; the name is what JSON shows)"},
    {"get", (PyCFunction)Signing_get, METH_O,
     "get((sysid, compid, link_id)) -> (last accepted timestamp, key slot) or None"},
    {"put", (PyCFunction)Signing_put, METH_VARARGS,
     "put((sysid, compid, link_id), last, key_slot): the stream's last accepted timestamp and its key"},
    {"__reduce__", (PyCFunction)Signing_reduce, METH_NOARGS, "refused: the state holds keys"},
    {"__reduce_ex__", (PyCFunction)Signing_reduce, METH_O, "refused: the state holds keys"},
    {"__copy__", (PyCFunction)Signing_reduce, METH_NOARGS, "refused: the state holds keys"},
    {"__deepcopy__", (PyCFunction)Signing_reduce, METH_O, "refused: the state holds keys"},
    {NULL, NULL, 0, NULL},
};

static PySequenceMethods Signing_as_sequence = {
    .sq_length = (lenfunc)Signing_len,
};

static PyTypeObject SigningType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "mavscope._native.SigningState",
    .tp_basicsize = sizeof(SigningObject),
    .tp_dealloc = (destructor)Signing_dealloc,
    .tp_repr = (reprfunc)Signing_repr,
    .tp_as_sequence = &Signing_as_sequence,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "MAVLink signing state shared by the native walker and SignatureVerifier (docs/native.md).",
    .tp_methods = Signing_methods,
    .tp_init = (initproc)Signing_init,
    .tp_new = PyType_GenericNew,
};

/* ---- Walker ------------------------------------------------------------------------------- */

/* The bytes of a pcap that grows while it is walked (`Walker.feed`): what the reader has not passed yet,
 * from file offset `base`. */
typedef struct {
    uint8_t *data;
    size_t len, cap;
    uint64_t base;
} fed_bytes;

static int64_t fed_read(void *ctx, uint8_t *dst, size_t n, uint64_t off, int *err) {
    const fed_bytes *f = ctx;
    if (off < f->base) { /* behind what was kept: never asked for (the reader reads on from its position) */
        *err = EIO;
        return -1;
    }
    if (off - f->base >= f->len)
        return 0;
    size_t k = f->len - (size_t)(off - f->base) < n ? f->len - (size_t)(off - f->base) : n;
    memcpy(dst, f->data + (off - f->base), k);
    return (int64_t)k;
}

typedef struct {
    PyObject_HEAD
    ms_walker walker;
    int fd;              /* the capture file, owned by the caller; -1: a fed pcap (live capture) */
    fed_bytes fed;       /* fd == -1: the bytes fed and not yet read, from file offset fed.base */
    int have_walker;
    int ended;
    int busy;
    PyObject *table;     /* TableObject, kept alive while the walker points into it */
    PyObject *endpoints; /* the Dissector's mavlink_endpoints */
    PyObject *endpoint;  /* endpoint(packed: bytes, port: int) -> an element of `endpoints` */
    PyObject *senders;   /* set[tuple[int, int]]: the security stage's SignedSenders, or a plain set */
    int signers_loaded;  /* the bitmap was loaded from `senders` (then: its epoch and how much of its log) */
    long long signers_epoch;
    Py_ssize_t signers_pos;
    PyObject *summary;   /* SummaryObject or NULL (JSON Lines) */
    PyObject *columns;   /* ColumnsObject or NULL: column mode */
    PyObject *receivers; /* the Dissector's receivers (dict: UDP port -> receivers), or NULL */
    PyObject *raw;       /* a raw stream's RawLink (the Dissector's `raw`: `frames`, `held`), or NULL */
    int waiting_stale;   /* Python may have changed `receivers` (it was handed a record) since they were read */
    int endpoints_full;  /* `endpoints` reached MS_MAX_ENDPOINTS and was loaded into the walker's memory once */
    ms_buf out;
} WalkerObject;

static void Walker_release(WalkerObject *self) {
    if (self->have_walker) {
        ms_walker_free(&self->walker);
        self->have_walker = 0;
    }
    ms_buf_free(&self->out);
    free(self->fed.data);
    memset(&self->fed, 0, sizeof self->fed);
    self->ended = 1;
}

static void Walker_dealloc(WalkerObject *self) {
    Walker_release(self);
    Py_XDECREF(self->table);
    Py_XDECREF(self->endpoints);
    Py_XDECREF(self->endpoint);
    Py_XDECREF(self->senders);
    Py_XDECREF(self->receivers);
    Py_XDECREF(self->raw);
    Py_XDECREF(self->summary);
    Py_XDECREF(self->columns);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int Walker_init(WalkerObject *self, PyObject *args, PyObject *kwds) {
    static char *kwlist[] = {"fd", "size", "kind", "table", "endpoints", "endpoint", "signed_senders", "window",
                             "summary", "t0", "columns", "receivers", "notes", "ports", "raw", NULL};
    PyObject *table, *endpoints, *endpoint, *senders, *summary = Py_None, *t0 = Py_None;
    PyObject *columns = Py_None, *receivers = Py_None, *notes = Py_None, *ports = Py_None, *raw = Py_None;
    int fd, kind;
    unsigned long long size;
    Py_ssize_t window = MS_WINDOW;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "iKiO!O!OO!|nOOOOOOO", kwlist, &fd, &size, &kind, &TableType,
                                     &table, &PySet_Type, &endpoints, &endpoint, &PySet_Type, &senders, &window,
                                     &summary, &t0, &columns, &receivers, &notes, &ports, &raw))
        return -1;
    static const Py_ssize_t pieces[MS_NOTE_TPLS] = {4, 4, 3}; /* walk.h MS_TPL_*: the values between them */
    if (notes != Py_None) { /* MS_NOTE_TPLS tuples of bytes objects, each at most MS_NOTE_TPL_MAX long */
        int ok = PyTuple_Check(notes) && PyTuple_GET_SIZE(notes) == MS_NOTE_TPLS;
        for (Py_ssize_t i = 0; ok && i < MS_NOTE_TPLS; i++) {
            PyObject *t = PyTuple_GET_ITEM(notes, i);
            ok = PyTuple_Check(t) && PyTuple_GET_SIZE(t) == pieces[i];
            for (Py_ssize_t j = 0; ok && j < pieces[i]; j++) {
                PyObject *b = PyTuple_GET_ITEM(t, j);
                ok = PyBytes_Check(b) && PyBytes_GET_SIZE(b) <= MS_NOTE_TPL_MAX;
            }
        }
        if (!ok) {
            PyErr_SetString(PyExc_TypeError, "notes must be 3 tuples of 4, 4 and 3 bytes (at most 256 each), or None");
            return -1;
        }
    }
    if (ports != Py_None) { /* a tuple of UDP ports */
        int ok = PyTuple_Check(ports) && PyTuple_GET_SIZE(ports) <= 1024;
        for (Py_ssize_t i = 0; ok && i < PyTuple_GET_SIZE(ports); i++) {
            PyObject *v = PyTuple_GET_ITEM(ports, i);
            long port = PyLong_Check(v) ? PyLong_AsLong(v) : -1;
            ok = 0 <= port && port <= 65535;
        }
        if (!ok) {
            PyErr_Clear();
            PyErr_SetString(PyExc_TypeError, "ports must be a tuple of at most 1024 UDP ports, or None");
            return -1;
        }
    }
    if (receivers != Py_None && !PyDict_Check(receivers)) {
        PyErr_SetString(PyExc_TypeError, "receivers must be a dict (the Dissector's receivers) or None");
        return -1;
    }
    if (columns != Py_None && (!PyObject_TypeCheck(columns, &ColumnsType) || ((ColumnsObject *)columns)->table != table ||
                               summary != Py_None)) {
        PyErr_SetString(PyExc_TypeError, "columns must be Columns of the same table (and no summary), or None");
        return -1;
    }
    if (summary != Py_None &&
        (!PyObject_TypeCheck(summary, &SummaryType) || ((SummaryObject *)summary)->table != table)) {
        PyErr_SetString(PyExc_TypeError, "summary must be a Summary of the same table, or None");
        return -1;
    }
    double t0v = 0.0;
    if (t0 != Py_None) {
        t0v = PyFloat_AsDouble(t0);
        if (t0v == -1.0 && PyErr_Occurred())
            return -1;
    }
    if (window < 64) { /* a resynchronisation scan looks at whole headers within one window */
        PyErr_SetString(PyExc_ValueError, "window must be at least 64 bytes");
        return -1;
    }
    if (kind < MS_KIND_PCAP || kind > MS_KIND_RAW) {
        PyErr_SetString(PyExc_ValueError, "unknown capture kind");
        return -1;
    }
    if (fd < -1 || (fd == -1 && (kind != MS_KIND_PCAP || size != 0))) {
        PyErr_SetString(PyExc_ValueError, "fd must be an open file descriptor, or -1 for a fed pcap of size 0");
        return -1;
    }
    if (!PyCallable_Check(endpoint)) {
        PyErr_SetString(PyExc_TypeError, "endpoint must be callable");
        return -1;
    }
    if (self->have_walker) {
        PyErr_SetString(PyExc_RuntimeError, "Walker already initialised");
        return -1;
    }
    self->fd = fd;
    Py_INCREF(table);
    self->table = table;
    Py_INCREF(endpoints);
    self->endpoints = endpoints;
    Py_INCREF(endpoint);
    self->endpoint = endpoint;
    Py_INCREF(senders);
    self->senders = senders;
    if (receivers != Py_None) {
        Py_INCREF(receivers);
        self->receivers = receivers;
        self->waiting_stale = 1;
    }
    if (raw != Py_None && kind == MS_KIND_RAW) {
        /* the stream's clean stretches are written here, or put into the columns (walk.c walk_raw); without it,
         * chunks are handed back */
        Py_INCREF(raw);
        self->raw = raw;
    }
    ms_buf_init(&self->out);
    ms_source src = {fed_read, &self->fed};
    if (fd != -1)
        src = ms_fd_source(&self->fd);
    ms_walker_init(&self->walker, src, (uint64_t)size, kind, &((TableObject *)table)->table);
    self->walker.reader.window = (size_t)window; /* bytes read at a time: the tests make it small */
    self->walker.raw_native = self->raw != NULL;
    if (summary != Py_None) {
        Py_INCREF(summary);
        self->summary = summary;
        self->walker.summary = &((SummaryObject *)summary)->summary;
        self->walker.has_t0 = t0 != Py_None;
        self->walker.t0 = t0v;
    }
    if (columns != Py_None) {
        Py_INCREF(columns);
        self->columns = columns;
        self->walker.cols = &((ColumnsObject *)columns)->cols;
    }
    if (ports != Py_None && PyTuple_GET_SIZE(ports) > 0) {
        const Py_ssize_t np = PyTuple_GET_SIZE(ports);
        uint16_t *list = malloc((size_t)np * sizeof *list);
        if (list == NULL) {
            ms_walker_free(&self->walker);
            PyErr_NoMemory();
            return -1;
        }
        for (Py_ssize_t i = 0; i < np; i++)
            list[i] = (uint16_t)PyLong_AsLong(PyTuple_GET_ITEM(ports, i));
        self->walker.ports = list;
        self->walker.nports = (size_t)np;
    }
    if (notes != Py_None) {
        for (Py_ssize_t i = 0; i < MS_NOTE_TPLS; i++)
            for (Py_ssize_t j = 0; j < pieces[i]; j++) {
                PyObject *b = PyTuple_GET_ITEM(PyTuple_GET_ITEM(notes, i), j);
                size_t n = (size_t)PyBytes_GET_SIZE(b);
                char *copy = malloc(n + 1);
                if (copy == NULL) {
                    ms_walker_free(&self->walker);
                    PyErr_NoMemory();
                    return -1;
                }
                memcpy(copy, PyBytes_AS_STRING(b), n);
                self->walker.note_tpl[i][j] = copy;
                self->walker.note_tpl_len[i][j] = n;
            }
    }
    self->have_walker = 1;
    self->ended = 0;
    return 0;
}

/* The record's time as a Python float (or None), exactly as the Python readers compute it. */
static PyObject *record_time(const ms_record *rec) {
    double t;
    int r = ms_record_time(rec, &t);
    if (r == 0)
        Py_RETURN_NONE;
    if (r > 0)
        return PyFloat_FromDouble(t);
    /* pcapng units beyond 2**64: ticks / (base ** exp) + tsoffset with Python ints */
    PyObject *ticks = PyLong_FromUnsignedLongLong(rec->ticks);
    PyObject *base = PyLong_FromLong(rec->units_pow2 ? 2 : 10);
    PyObject *exp = PyLong_FromLong(rec->units_exp);
    PyObject *off = PyLong_FromLongLong(rec->tsoffset);
    PyObject *units = NULL, *q = NULL, *res = NULL;
    if (ticks && base && exp && off && (units = PyNumber_Power(base, exp, Py_None)) != NULL &&
        (q = PyNumber_TrueDivide(ticks, units)) != NULL)
        res = PyNumber_Add(q, off);
    Py_XDECREF(ticks);
    Py_XDECREF(base);
    Py_XDECREF(exp);
    Py_XDECREF(off);
    Py_XDECREF(units);
    Py_XDECREF(q);
    return res;
}

#define CALENDAR_END 253402300800.0

/* The time-out-of-range note of a record whose time C could not compute (MS_NOTE_TIME_CHECK): the text of
 * capture/pcapng.py _time_note, or Py_None when the time is in range. */
static PyObject *time_note(const ms_record *rec, PyObject *time, const char *iface, Py_ssize_t iface_len,
                           int64_t offset) {
    double t = PyFloat_AsDouble(time);
    if (t == -1.0 && PyErr_Occurred())
        return NULL;
    if (0.0 <= t && t < CALENDAR_END)
        Py_RETURN_NONE;
    PyObject *spec = PyUnicode_FromString(".6g");
    PyObject *shown = spec ? PyObject_Format(time, spec) : NULL;
    PyObject *base = PyLong_FromLong(rec->units_pow2 ? 2 : 10);
    PyObject *exp = PyLong_FromLong(rec->units_exp);
    PyObject *which = PyUnicode_FromStringAndSize(iface, iface_len);
    PyObject *units = NULL, *text = NULL, *res = NULL;
    if (shown && base && exp && which && (units = PyNumber_Power(base, exp, Py_None)) != NULL)
        text = PyUnicode_FromFormat("packet time %U s since 1970 (interface %U: if_tsoffset %lld s, %S ticks/s)",
                                    shown, which, (long long)rec->tsoffset, units);
    if (text != NULL)
        res = Py_BuildValue("(sNL)", "time-out-of-range", text, (long long)offset);
    Py_XDECREF(shown);
    Py_XDECREF(which);
    Py_XDECREF(spec);
    Py_XDECREF(base);
    Py_XDECREF(exp);
    Py_XDECREF(units);
    return res;
}

static PyObject *handback_tuple(const ms_record *rec) {
    PyObject *time = record_time(rec);
    if (time == NULL)
        return NULL;
    const ms_notes *ns = rec->notes;
    PyObject *notes = PyList_New(0);
    if (notes == NULL) {
        Py_DECREF(time);
        return NULL;
    }
    for (size_t i = 0; ns && i < ns->n; i++) {
        const ms_note *n = &ns->v[i];
        const char *msg = ns->text.data + n->msg_off;
        PyObject *item;
        if (n->code == MS_NOTE_TIME_CHECK)
            item = time_note(rec, time, msg, (Py_ssize_t)n->msg_len, n->offset);
        else
            item = Py_BuildValue("(ss#L)", ms_note_code_name(n->code), msg, (Py_ssize_t)n->msg_len,
                                 (long long)n->offset);
        if (item == NULL || (item != Py_None && PyList_Append(notes, item) != 0)) {
            Py_XDECREF(item);
            Py_DECREF(notes);
            Py_DECREF(time);
            return NULL;
        }
        Py_DECREF(item);
    }
    PyObject *data = PyBytes_FromStringAndSize((const char *)rec->data, (Py_ssize_t)rec->len);
    PyObject *tnotes = PyList_AsTuple(notes);
    Py_DECREF(notes);
    if (data == NULL || tnotes == NULL) {
        Py_XDECREF(data);
        Py_XDECREF(tnotes);
        Py_DECREF(time);
        return NULL;
    }
    return Py_BuildValue("(KNLNKKN)", (unsigned long long)rec->number, time, (long long)rec->linktype, data,
                         (unsigned long long)rec->offset, (unsigned long long)rec->orig_len, tnotes);
}

/* Mark one item of the senders' set in the bitmap (items other than two ints 0..255 are ignored: the
 * security stage only stores (sysid, compid)). */
static void set_signer(WalkerObject *self, PyObject *key) {
    if (PyTuple_Check(key) && PyTuple_GET_SIZE(key) == 2) {
        long a = PyLong_AsLong(PyTuple_GET_ITEM(key, 0));
        long b = PyLong_AsLong(PyTuple_GET_ITEM(key, 1));
        if (PyErr_Occurred())
            PyErr_Clear();
        else if (a >= 0 && a <= 255 && b >= 0 && b <= 255)
            ms_signer_set(&self->walker, (unsigned)((a << 8) | b));
    }
}

/* Load the bitmap of senders seen signing from the whole Python set. */
static int load_signers(WalkerObject *self) {
    memset(self->walker.signers, 0, sizeof self->walker.signers);
    PyObject *it = PyObject_GetIter(self->senders);
    if (it == NULL)
        return -1;
    PyObject *key;
    while ((key = PyIter_Next(it)) != NULL) {
        set_signer(self, key);
        Py_DECREF(key);
    }
    Py_DECREF(it);
    return PyErr_Occurred() ? -1 : 0;
}

/* Bring the bitmap up to date before a batch. The security stage's SignedSenders keeps the senders Python
 * added, in order (`log`), and counts its clears (`epoch`): only the log's new entries are read, unless it
 * was cleared since. A plain set is read whole. (Reading the whole set before every batch was quadratic: a
 * batch ends at each record handed back, and with a key every new signing stream is one.) */
/* How many new endpoints the Dissector's mavlink_endpoints still takes (Dissector._learn: at most
 * MS_MAX_ENDPOINTS, the first ones kept). Once it is full it never changes again: its endpoints are loaded
 * into the walker's memory of those reported, so that a source Python remembers is not handed back. */
static int sync_endpoints(WalkerObject *self) {
    Py_ssize_t size = PySet_GET_SIZE(self->endpoints);
    ms_walker *w = &self->walker;
    w->endpoint_room = size >= MS_MAX_ENDPOINTS ? 0 : (size_t)(MS_MAX_ENDPOINTS - size);
    if (size < MS_MAX_ENDPOINTS || self->endpoints_full)
        return 0;
    PyObject *it = PyObject_GetIter(self->endpoints);
    if (it == NULL)
        return -1;
    PyObject *ep;
    while ((ep = PyIter_Next(it)) != NULL) {
        PyObject *address = PyObject_GetAttrString(ep, "address");
        PyObject *packed = address != NULL ? PyObject_GetAttrString(address, "packed") : NULL;
        PyObject *port = packed != NULL ? PyObject_GetAttrString(ep, "port") : NULL;
        long p = port != NULL ? PyLong_AsLong(port) : -1;
        int ok = packed != NULL && PyBytes_Check(packed) && p >= 0 && p <= 65535 && !PyErr_Occurred();
        if (ok) {
            ms_endpoint e;
            memset(&e, 0, sizeof e);
            Py_ssize_t n = PyBytes_GET_SIZE(packed);
            e.v6 = n == 16;
            memcpy(e.addr, PyBytes_AS_STRING(packed), n == 16 ? 16 : 4);
            e.port = (uint16_t)p;
            ok = (n == 4 || n == 16) && ms_walker_remember_endpoint(w, &e) == 0;
            if (!ok && !PyErr_Occurred())
                PyErr_NoMemory();
        }
        Py_XDECREF(port);
        Py_XDECREF(packed);
        Py_XDECREF(address);
        Py_DECREF(ep);
        if (!ok) {
            Py_DECREF(it);
            return -1;
        }
    }
    Py_DECREF(it);
    if (PyErr_Occurred())
        return -1;
    self->endpoints_full = 1;
    return 0;
}

static int sync_signers(WalkerObject *self) {
    PyObject *log = PyObject_GetAttrString(self->senders, "log");
    PyObject *epoch_obj = log != NULL ? PyObject_GetAttrString(self->senders, "epoch") : NULL;
    long long epoch = epoch_obj != NULL ? PyLong_AsLongLong(epoch_obj) : -1;
    Py_XDECREF(epoch_obj);
    if (log == NULL || !PyList_Check(log) || epoch < 0) {
        Py_XDECREF(log);
        PyErr_Clear();
        self->signers_loaded = 0;
        return load_signers(self);
    }
    int r = 0;
    if (!self->signers_loaded || epoch != self->signers_epoch || PyList_GET_SIZE(log) < self->signers_pos) {
        r = load_signers(self);
    } else {
        /* the size read again each step, the item held while it is read: a conversion could run code */
        for (Py_ssize_t i = self->signers_pos; i < PyList_GET_SIZE(log); i++) {
            PyObject *key = PyList_GET_ITEM(log, i);
            Py_INCREF(key);
            set_signer(self, key);
            Py_DECREF(key);
        }
    }
    const Py_ssize_t n = PyList_GET_SIZE(log);
    Py_DECREF(log);
    if (r != 0) {
        self->signers_loaded = 0;
        return -1;
    }
    self->signers_loaded = 1;
    self->signers_epoch = epoch;
    self->signers_pos = n;
    return 0;
}

/* Push what the batch added into the Python sets. */
static int push_state(WalkerObject *self) {
    ms_walker *w = &self->walker;
    for (size_t i = 0; i < w->n_new_signers; i++) {
        PyObject *t = Py_BuildValue("(ii)", w->new_signers[i] >> 8, w->new_signers[i] & 0xFF);
        if (t == NULL || PySet_Add(self->senders, t) != 0) {
            Py_XDECREF(t);
            return -1;
        }
        Py_DECREF(t);
    }
    w->n_new_signers = 0;
    for (size_t i = 0; i < w->n_new_endpoints; i++) {
        const ms_endpoint *e = &w->new_endpoints[i];
        PyObject *ep = PyObject_CallFunction(self->endpoint, "y#i", (const char *)e->addr, (Py_ssize_t)(e->v6 ? 16 : 4),
                                             (int)e->port);
        if (ep == NULL || PySet_Add(self->endpoints, ep) != 0) {
            Py_XDECREF(ep);
            return -1;
        }
        Py_DECREF(ep);
    }
    w->n_new_endpoints = 0;
    return 0;
}

/* Read the UDP ports Python's receivers wait on into the walker (after a handed-back record, the only thing
 * that changes them): the keys of the Dissector's `receivers`, ints (mavscope.mavlink.receivers.Sockets.ports:
 * a receiving socket is a port, whatever address a datagram to it has). */
static int sync_waiting(WalkerObject *self) {
    ms_walker *w = &self->walker;
    w->n_waiting = 0;
    PyObject *keys = PyDict_Keys(self->receivers);
    if (keys == NULL)
        return -1;
    Py_ssize_t n = PyList_GET_SIZE(keys);
    if (n > 0 && ms_walker_waiting_room(w, (size_t)n) != 0) {
        Py_DECREF(keys);
        PyErr_NoMemory();
        return -1;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        long pv = PyLong_AsLong(PyList_GET_ITEM(keys, i));
        if ((pv == -1 && PyErr_Occurred()) || pv < 0 || pv > 65535) {
            Py_DECREF(keys);
            if (!PyErr_Occurred())
                PyErr_SetString(PyExc_TypeError, "receivers' keys must be UDP ports");
            return -1;
        }
        ms_endpoint *e = &w->waiting[w->n_waiting++];
        memset(e, 0, sizeof *e);
        e->port = (uint16_t)pv;
    }
    Py_DECREF(keys);
    self->waiting_stale = 0;
    return 0;
}

/* Read the raw stream's state from Python's RawLink before a step: the frames it numbered so far (its framer
 * numbers on from those the walker writes) and whether its framer is idle (`held` -1) or how many bytes it
 * holds (the walker hands back the next piece: walk.c walk_raw). */
static int sync_raw(WalkerObject *self) {
    PyObject *frames = PyObject_GetAttrString(self->raw, "frames");
    if (frames == NULL)
        return -1;
    unsigned long long n = PyLong_AsUnsignedLongLong(frames);
    Py_DECREF(frames);
    if (n == (unsigned long long)-1 && PyErr_Occurred())
        return -1;
    PyObject *held = PyObject_GetAttrString(self->raw, "held");
    if (held == NULL)
        return -1;
    long long h = PyLong_AsLongLong(held);
    Py_DECREF(held);
    if (h == -1 && PyErr_Occurred())
        return -1;
    if (h < -1) {
        PyErr_SetString(PyExc_ValueError, "RawLink.held must be -1 or a count of bytes");
        return -1;
    }
    self->walker.raw_frames = (uint64_t)n;
    self->walker.raw_held = (int64_t)h;
    return 0;
}

static PyObject *Walker_next(WalkerObject *self, PyObject *args, PyObject *kwds) {
    static char *kwlist[] = {"signed_nokey", "limit", "into", "signing", NULL};
    int nokey = 0;
    Py_ssize_t limit = 1 << 20;
    PyObject *into = Py_None, *signing = Py_None;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "|pnOO", kwlist, &nokey, &limit, &into, &signing))
        return NULL;
    if (signing != Py_None && !PyObject_TypeCheck(signing, &SigningType)) {
        PyErr_SetString(PyExc_TypeError, "signing must be a SigningState or None");
        return NULL;
    }
    if (signing != Py_None && ((SigningObject *)signing)->busy) {
        PyErr_SetString(PyExc_RuntimeError, "SigningState is in use by another walk");
        return NULL;
    }
    if (into != Py_None && !PyByteArray_CheckExact(into)) {
        PyErr_SetString(PyExc_TypeError, "into must be a bytearray or None");
        return NULL;
    }
    if (self->busy) {
        PyErr_SetString(PyExc_RuntimeError, "Walker.next is already running");
        return NULL;
    }
    if (self->ended || !self->have_walker)
        Py_RETURN_NONE;
    if (limit < 1)
        limit = 1;
    if (sync_signers(self) != 0 || sync_endpoints(self) != 0)
        return NULL;
    if (self->waiting_stale && sync_waiting(self) != 0)
        return NULL;
    self->walker.hand_back_all = 0;
    if (self->receivers != NULL && !PyDict_CheckExact(self->receivers)) {
        /* the Dissector's receivers say whether every record must be handed back (`hand_back`: a TCP hole waits,
         * and any record's time may end it); only Python changes it, between calls */
        PyObject *all = PyObject_GetAttrString(self->receivers, "hand_back");
        int yes = all == NULL ? -1 : PyObject_IsTrue(all);
        Py_XDECREF(all);
        if (yes < 0)
            return NULL;
        self->walker.hand_back_all = yes;
    }
    if (self->raw != NULL && sync_raw(self) != 0)
        return NULL;
    ColumnsObject *cols = (ColumnsObject *)self->columns;
    if (cols != NULL && (cols->busy || cols->cols.failed)) {
        PyErr_SetString(PyExc_RuntimeError, cols->busy ? "another Walker is filling these Columns"
                                                       : "these Columns ran out of memory");
        return NULL;
    }
    SigningObject *state = nokey || signing == Py_None ? NULL : (SigningObject *)signing;
    self->walker.sign_mode = nokey ? MS_SIGNED_NOKEY : state != NULL ? MS_SIGNED_VERIFY : MS_SIGNED_HANDBACK;
    self->walker.signing = state != NULL ? &state->state : NULL;
    self->out.len = 0;
    ms_record rec;
    int r;
    self->busy = 1;
    if (cols != NULL)
        cols->busy = 1;
    if (state != NULL) {
        Py_INCREF(state);
        state->busy = 1;
    }
    Py_BEGIN_ALLOW_THREADS
    r = ms_walk(&self->walker, &self->out, (size_t)limit, &rec);
    Py_END_ALLOW_THREADS
    self->busy = 0;
    if (cols != NULL)
        cols->busy = 0;
    self->walker.signing = NULL;
    if (state != NULL) {
        state->busy = 0;
        Py_DECREF(state);
    }
    if (r == MS_WALK_NOMEM) {
        Walker_release(self);
        return PyErr_NoMemory();
    }
    if (push_state(self) != 0)
        return NULL;
    if (self->raw != NULL) { /* the frames this step numbered: Python's frames of the stream go on from them */
        PyObject *frames = PyLong_FromUnsignedLongLong((unsigned long long)self->walker.raw_frames);
        int bad = frames == NULL || PyObject_SetAttrString(self->raw, "frames", frames) != 0;
        Py_XDECREF(frames);
        if (bad)
            return NULL;
    }
    PyObject *list = PyList_New(0);
    if (list == NULL)
        return NULL;
    if (self->out.len) {
        /* into a bytearray the caller recycles (its memory stays mapped: no fresh pages per batch), or
         * a new bytes object */
        PyObject *chunk;
        if (into != Py_None) {
            chunk = into;
            Py_INCREF(chunk);
            if (PyByteArray_Resize(chunk, (Py_ssize_t)self->out.len) != 0) {
                Py_DECREF(chunk);
                Py_DECREF(list);
                return NULL;
            }
            memcpy(PyByteArray_AS_STRING(chunk), self->out.data, self->out.len);
        } else {
            chunk = PyBytes_FromStringAndSize(self->out.data, (Py_ssize_t)self->out.len);
        }
        if (chunk == NULL || PyList_Append(list, chunk) != 0) {
            Py_XDECREF(chunk);
            Py_DECREF(list);
            return NULL;
        }
        Py_DECREF(chunk);
    }
    if (r == MS_WALK_HANDBACK) {
        self->waiting_stale = self->receivers != NULL;
        PyObject *t = handback_tuple(&rec);
        if (t == NULL || PyList_Append(list, t) != 0) {
            Py_XDECREF(t);
            Py_DECREF(list);
            return NULL;
        }
        Py_DECREF(t);
    } else if (r == MS_WALK_END) {
        self->ended = 1;
        if (PyList_GET_SIZE(list) == 0) {
            Py_DECREF(list);
            Py_RETURN_NONE;
        }
    }
    if (self->out.cap > (8u << 20)) /* do not keep a huge buffer after one long line */
        ms_buf_free(&self->out);
    return list;
}

static PyObject *Walker_walked(WalkerObject *self, PyObject *Py_UNUSED(ignored)) {
    if (!self->have_walker || self->walker.n_walked == 0)
        Py_RETURN_NONE;
    PyObject *time = record_time(&self->walker.walked);
    if (time == NULL)
        return NULL;
    if (self->walker.py_index < 0)
        return Py_BuildValue("(KNO)", (unsigned long long)self->walker.walked.number, time, Py_None);
    return Py_BuildValue("(KNL)", (unsigned long long)self->walker.walked.number, time,
                         (long long)self->walker.py_index);
}

static PyObject *Walker_feed(WalkerObject *self, PyObject *arg) {
    if (self->fd != -1) {
        PyErr_SetString(PyExc_TypeError, "feed() is for a Walker made with fd=-1");
        return NULL;
    }
    if (self->busy) {
        PyErr_SetString(PyExc_RuntimeError, "Walker.next is running");
        return NULL;
    }
    if (!self->have_walker) {
        PyErr_SetString(PyExc_ValueError, "the Walker is closed");
        return NULL;
    }
    Py_buffer b;
    if (PyObject_GetBuffer(arg, &b, PyBUF_SIMPLE) != 0)
        return NULL;
    fed_bytes *f = &self->fed;
    ms_reader *r = &self->walker.reader;
    if (r->started && r->pos > f->base) { /* the reader has passed these bytes for good */
        size_t k = r->pos - f->base < f->len ? (size_t)(r->pos - f->base) : f->len;
        memmove(f->data, f->data + k, f->len - k);
        f->len -= k;
        f->base += k;
    }
    size_t need = f->len + (size_t)b.len;
    if (need > f->cap) {
        size_t cap = f->cap ? f->cap : 65536;
        while (cap < need)
            cap *= 2;
        uint8_t *p = realloc(f->data, cap);
        if (p == NULL) {
            PyBuffer_Release(&b);
            return PyErr_NoMemory();
        }
        f->data = p;
        f->cap = cap;
    }
    if (b.len)
        memcpy(f->data + f->len, b.buf, (size_t)b.len);
    f->len = need;
    PyBuffer_Release(&b);
    if (ms_reader_extend(r, f->base + f->len) != 0) {
        PyErr_SetString(PyExc_ValueError, "the fed pcap did not end with a whole record: it cannot grow");
        return NULL;
    }
    self->ended = 0;
    Py_RETURN_NONE;
}

static PyObject *Walker_close(WalkerObject *self, PyObject *Py_UNUSED(ignored)) {
    if (self->busy) {
        PyErr_SetString(PyExc_RuntimeError, "Walker.next is running");
        return NULL;
    }
    Walker_release(self);
    Py_RETURN_NONE;
}

static PyObject *Walker_stats(WalkerObject *self, PyObject *Py_UNUSED(ignored)) {
    const ms_walker *w = &self->walker;
    return Py_BuildValue("{sKsKsKsKsK}", "records_native", (unsigned long long)w->records_native,
                         "records_handed_back", (unsigned long long)w->records_handed_back, "frames_native",
                         (unsigned long long)w->frames_native, "position",
                         (unsigned long long)(self->have_walker ? w->reader.position : 0), "size",
                         (unsigned long long)(self->have_walker ? w->reader.size : 0));
}

static PyMethodDef Walker_methods[] = {
    {"next", (PyCFunction)(void (*)(void))Walker_next, METH_VARARGS | METH_KEYWORDS,
     "next(signed_nokey=False, limit=1<<20, into=None, signing=None): the next segments (JSON lines as bytes, "
     "or in the bytearray `into`; a handed-back record tuple, which always comes last), or None at the end; "
     "with `signing` (a SigningState) signed frames of known streams are judged against it"},
    {"walked", (PyCFunction)Walker_walked, METH_NOARGS,
     "(number, time, index) of the last record the last next() walked natively (before a handed-back one), "
     "or None when it walked none; index: the frame index Python's dissector would hold after them, or None "
     "when they leave it unchanged"},
    {"stats", (PyCFunction)Walker_stats, METH_NOARGS,
     "counters of the walk, the file position reached and the file size (smaller if the file shrank)"},
    {"feed", (PyCFunction)Walker_feed, METH_O,
     "feed(records): append bytes (whole pcap records; the global header first) to a Walker made with fd=-1"},
    {"close", (PyCFunction)Walker_close, METH_NOARGS, "release the walker's memory (the caller closes the file)"},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject WalkerType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "mavscope._native.Walker",
    .tp_basicsize = sizeof(WalkerObject),
    .tp_dealloc = (destructor)Walker_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Walks a capture file, writing JSON Lines and handing records back.",
    .tp_methods = Walker_methods,
    .tp_init = (initproc)Walker_init,
    .tp_new = PyType_GenericNew,
};

/* ---- module functions (tests) ------------------------------------------------------------- */

static PyObject *format_double(PyObject *Py_UNUSED(mod), PyObject *arg) {
    double v = PyFloat_AsDouble(arg);
    if (v == -1.0 && PyErr_Occurred())
        return NULL;
    char out[MS_DOUBLE_MAX];
    int n = ms_fmt_double(v, out);
    return PyBytes_FromStringAndSize(out, n);
}

static PyObject *text_json(PyObject *Py_UNUSED(mod), PyObject *arg) {
    Py_buffer b;
    if (PyObject_GetBuffer(arg, &b, PyBUF_SIMPLE) != 0)
        return NULL;
    ms_buf out;
    ms_buf_init(&out);
    ms_put_text(&out, (const uint8_t *)b.buf, (size_t)b.len);
    PyBuffer_Release(&b);
    if (out.failed) {
        ms_buf_free(&out);
        return PyErr_NoMemory();
    }
    PyObject *res = PyBytes_FromStringAndSize(out.data ? out.data : "", (Py_ssize_t)out.len);
    ms_buf_free(&out);
    return res;
}

/* format_f32(x, layout): the float32 nearest x (as a C cast rounds) as JSON (layout 0) or repr (1) */
static PyObject *format_f32(PyObject *Py_UNUSED(mod), PyObject *args) {
    double v;
    int layout;
    if (!PyArg_ParseTuple(args, "di", &v, &layout))
        return NULL;
    char out[MS_DOUBLE_MAX];
    const float f = (float)v;
    return PyBytes_FromStringAndSize(out, (layout ? ms_w_f32_repr(out, f) : ms_w_f32(out, f)) - out);
}

static PyObject *format_double_repr(PyObject *Py_UNUSED(mod), PyObject *arg) {
    double v = PyFloat_AsDouble(arg);
    if (v == -1.0 && PyErr_Occurred())
        return NULL;
    char out[MS_DOUBLE_MAX];
    return PyBytes_FromStringAndSize(out, ms_w_double_repr(out, v) - out);
}

static PyObject *format_degrees(PyObject *Py_UNUSED(mod), PyObject *args) {
    unsigned long long bits;
    int is_unsigned;
    if (!PyArg_ParseTuple(args, "Kp", &bits, &is_unsigned))
        return NULL;
    char out[MS_DEG_MAX];
    return PyBytes_FromStringAndSize(out, ms_w_degrees(out, (int64_t)bits, is_unsigned) - out);
}

static PyObject *format_reltime(PyObject *Py_UNUSED(mod), PyObject *arg) {
    double v = PyFloat_AsDouble(arg);
    if (v == -1.0 && PyErr_Occurred())
        return NULL;
    char out[MS_REL_MAX];
    char *end = ms_w_reltime(out, v);
    if (end == NULL)
        Py_RETURN_NONE;
    return PyBytes_FromStringAndSize(out, end - out);
}

static PyObject *repr_ascii(PyObject *Py_UNUSED(mod), PyObject *arg) {
    Py_buffer b;
    if (PyObject_GetBuffer(arg, &b, PyBUF_SIMPLE) != 0)
        return NULL;
    char *out = PyMem_Malloc(4 * (size_t)b.len + 2);
    if (out == NULL) {
        PyBuffer_Release(&b);
        return PyErr_NoMemory();
    }
    char *end = ms_w_repr_ascii(out, (const uint8_t *)b.buf, (size_t)b.len);
    PyBuffer_Release(&b);
    PyObject *res = end == NULL ? Py_NewRef(Py_None) : PyBytes_FromStringAndSize(out, end - out);
    PyMem_Free(out);
    return res;
}

static PyObject *sha256(PyObject *Py_UNUSED(mod), PyObject *arg) {
    Py_buffer b;
    if (PyObject_GetBuffer(arg, &b, PyBUF_SIMPLE) != 0)
        return NULL;
    ms_sha256 h;
    uint8_t digest[MS_SHA256_LEN];
    ms_sha256_init(&h);
    /* in uneven pieces, so the tests cover the block buffer's every fill level */
    size_t done = 0, piece = 1;
    while (done < (size_t)b.len) {
        size_t take = (size_t)b.len - done < piece ? (size_t)b.len - done : piece;
        ms_sha256_update(&h, (const uint8_t *)b.buf + done, take);
        done += take;
        piece = piece * 3 % 97 + 1;
    }
    PyBuffer_Release(&b);
    ms_sha256_final(&h, digest);
    return PyBytes_FromStringAndSize((const char *)digest, MS_SHA256_LEN);
}

static PyObject *format_skew(PyObject *Py_UNUSED(mod), PyObject *arg) {
    double v = PyFloat_AsDouble(arg);
    if (v == -1.0 && PyErr_Occurred())
        return NULL;
    char out[MS_DOUBLE_MAX];
    return PyBytes_FromStringAndSize(out, ms_w_double(out, ms_round6(v)) - out);
}

static PyMethodDef module_methods[] = {
    {"sha256", sha256, METH_O, "SHA-256 of a bytes-like object by the native code (fed in uneven pieces)"},
    {"format_skew", format_skew, METH_O, "JSON text of round(x, 6) as the native writer makes a skew"},
    {"format_f32", format_f32, METH_VARARGS, "format_f32(x, repr): a float32's shortest text, JSON or repr layout"},
    {"format_double_repr", format_double_repr, METH_O, "repr(x) of a finite double as the summary writer makes it"},
    {"format_degrees", format_degrees, METH_VARARGS, "f'{v / 1e7:.7f}' of a 64-bit integer (bits, unsigned)"},
    {"format_reltime", format_reltime, METH_O, "f'{t:11.6f}' as the summary writer makes it, or None"},
    {"repr_ascii", repr_ascii, METH_O, "repr() of char_text(b), or None when b is not ASCII"},
    {"format_double", format_double, METH_O, "JSON text of a float, as the native writer makes it"},
    {"text_json", text_json, METH_O, "JSON string of bytes decoded as UTF-8 with backslashreplace"},
    {"records_to_micro", ms_py_records_to_micro, METH_O,
     "records_to_micro(records): a live batch's records with microsecond times as the pcap writer writes them, "
     "and their number"},
    {"join_fields", ms_py_join_fields, METH_VARARGS,
     "join_fields(columns, separator, quote): the -T fields lines of columns of cells (lists of str or None, "
     "int64 buffers)"},
    {"udp_record", ms_py_udp_record, METH_VARARGS,
     "udp_record(sec, nsec, src, sport, dst, dport, payload): the pcap record live capture makes of a datagram"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef native_module = {
    PyModuleDef_HEAD_INIT, "mavscope._native", "The native fast path of mavscope (docs/native.md).", -1,
    module_methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__native(void) {
    if (PyType_Ready(&TableType) < 0 || PyType_Ready(&SummaryType) < 0 || PyType_Ready(&WalkerType) < 0 ||
        PyType_Ready(&BlockType) < 0 || PyType_Ready(&ColumnsType) < 0 ||
        PyType_Ready(&SigningType) < 0)
        return NULL;
    PyObject *m = PyModule_Create(&native_module);
    if (m == NULL)
        return NULL;
    PyObject *names = PyTuple_New(MS_NCOLS);
    if (names == NULL) {
        Py_DECREF(m);
        return NULL;
    }
    for (int k = 0; k < MS_NCOLS; k++) {
        PyObject *n = PyUnicode_FromString(MS_COL_NAMES[k]);
        if (n == NULL) {
            Py_DECREF(names);
            Py_DECREF(m);
            return NULL;
        }
        PyTuple_SET_ITEM(names, k, n);
    }
    if (PyModule_AddObject(m, "COLUMN_NAMES", names) < 0) {
        Py_DECREF(names);
        Py_DECREF(m);
        return NULL;
    }
    Py_INCREF(&TableType);
    Py_INCREF(&WalkerType);
    Py_INCREF(&SummaryType);
    Py_INCREF(&BlockType);
    Py_INCREF(&ColumnsType);
    Py_INCREF(&SigningType);
    if (PyModule_AddObject(m, "Table", (PyObject *)&TableType) < 0 ||
        PyModule_AddObject(m, "Walker", (PyObject *)&WalkerType) < 0 ||
        PyModule_AddObject(m, "Summary", (PyObject *)&SummaryType) < 0 ||
        PyModule_AddObject(m, "SigningState", (PyObject *)&SigningType) < 0 ||
        PyModule_AddObject(m, "Block", (PyObject *)&BlockType) < 0 ||
        PyModule_AddObject(m, "Columns", (PyObject *)&ColumnsType) < 0 ||
        PyModule_AddIntConstant(m, "MAX_ENDPOINTS", MS_MAX_ENDPOINTS) < 0 ||
        PyModule_AddIntConstant(m, "KIND_PCAP", MS_KIND_PCAP) < 0 ||
        PyModule_AddIntConstant(m, "KIND_PCAPNG", MS_KIND_PCAPNG) < 0 ||
        PyModule_AddIntConstant(m, "KIND_TLOG", MS_KIND_TLOG) < 0 ||
        PyModule_AddIntConstant(m, "KIND_RAW", MS_KIND_RAW) < 0 ||
        PyModule_AddIntConstant(m, "COLUMN_TRANSPORT_UDP", MS_TRANSPORT_UDP) < 0 ||
        PyModule_AddIntConstant(m, "NOTE_UNSIGNED", MS_NOTE_UNSIGNED) < 0 ||
        PyModule_AddIntConstant(m, "NOTE_V1", MS_NOTE_V1) < 0 ||
        PyModule_AddIntConstant(m, "NOTE_BAD_CRC", MS_NOTE_BAD_CRC) < 0 ||
        PyModule_AddIntConstant(m, "COLUMN_TRANSPORT_TLOG", MS_TRANSPORT_TLOG) < 0 ||
        PyModule_AddIntConstant(m, "COLUMN_TRANSPORT_RAW", MS_TRANSPORT_RAW) < 0 ||
        PyModule_AddIntConstant(m, "TABLE_VERSION", 1) < 0 || ms_py_add_receiver(m) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
