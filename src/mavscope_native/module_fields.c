/* join_fields(columns, bounds, modes, separator, quote, aggregator) -> str: the lines of `read -T fields`.
 *
 * mavscope.output.fields_batch makes, per `-e` field, a column for the lines of whole records, line g being
 * the record of rows bounds[g]..bounds[g + 1] (an int64 buffer of G + 1 offsets). A column is a list of G
 * cells, each a str or None (no value: an empty cell), or a value per row: an int64 buffer (numpy) of
 * header numbers, written in decimal, or a pair (texts, ids): a list of str or None and an int64 buffer of
 * each row's position in it (ids None: the texts are the rows'), or a triple (kind, values, present) of
 * payload numbers: "f4" float32 values written as their shortest text (repr's layout, nan and inf as repr
 * writes them), "i8" int64 values, and a byte per row, 0 where the row has none. Of a value per row the
 * cell is the record's first row's (mode 'r'), or of the values its rows have the first ('f'), the last
 * ('l') or all joined by `aggregator` ('a'); `modes` has a byte per column. Line g is its cells joined by `separator`, each cell that has a value in `quote`
 * (empty: none) with a quote inside doubled (the aggregator's too), then "\n". The Python form
 * (fields_batch.join_cells) is the reference: tests/cli/test_fields_batch.py holds the two equal. */
#define PY_SSIZE_T_CLEAN
#include "module_fields.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "buf.h"
#include "fmt.h"

typedef struct {
    PyObject *list;  /* a cell per line (str or None), or for a coded column its texts */
    Py_buffer view;  /* an int64 buffer: the numbers, or a coded column's ids; a payload numbers' values */
    int have_view;
    int coded;       /* `list` holds the texts the ids point into */
    char number;     /* payload numbers: 'f' float32, 'i' int64 values, with `present` (0: not such) */
    Py_buffer present;
    int have_present;
} column;

static char *put_int(char *p, int64_t v) {
    char tmp[24];
    int k = 0;
    uint64_t u = v < 0 ? (uint64_t)0 - (uint64_t)v : (uint64_t)v;
    do {
        tmp[k++] = (char)('0' + u % 10);
        u /= 10;
    } while (u);
    if (v < 0)
        *p++ = '-';
    while (k)
        *p++ = tmp[--k];
    return p;
}

static void release(column *cols, Py_ssize_t n) {
    for (Py_ssize_t k = 0; k < n; k++) {
        if (cols[k].have_view)
            PyBuffer_Release(&cols[k].view);
        if (cols[k].have_present)
            PyBuffer_Release(&cols[k].present);
    }
    PyMem_Free(cols);
}

static int int64_view(PyObject *c, Py_buffer *view) {
    if (PyObject_GetBuffer(c, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
        return -1;
    const char *f = view->format;
    if (view->itemsize != 8 || f == NULL ||
        !(strcmp(f, "q") == 0 || strcmp(f, "l") == 0 || strcmp(f, "<q") == 0 || strcmp(f, "=q") == 0)) {
        PyBuffer_Release(view);
        PyErr_SetString(PyExc_TypeError, "join_fields: a column is a list or an int64 buffer");
        return -1;
    }
    return 0;
}

static void put_number(ms_buf *out, int64_t v) {
    char *p = ms_buf_room(out, 24);
    if (p == NULL)
        return;
    out->len += (size_t)(put_int(p, v) - p);
}

/* `n` bytes of `s` inside a quoted cell: a quote doubled (`q` 0: no quoting, copied as they are) */
static void put_text(ms_buf *out, const char *s, Py_ssize_t n, char q) {
    if (!q) {
        ms_buf_put(out, s, (size_t)n);
        return;
    }
    const char *at = s, *end = s + n, *hit;
    while ((hit = memchr(at, q, (size_t)(end - at))) != NULL) {
        ms_buf_put(out, at, (size_t)(hit - at) + 1);
        ms_buf_byte(out, q);
        at = hit + 1;
    }
    ms_buf_put(out, at, (size_t)(end - at));
}

/* The text of a row `r` of a value per row: NULL for none, or its UTF-8 (`*n` bytes; a number's written in
 * `scratch`, MS_DOUBLE_MAX bytes); -1 in `*err` when a text is neither a str nor None or an id is out of
 * range (an exception set). */
static const char *coded_text(const column *c, int64_t r, Py_ssize_t *n, int *err, char *scratch) {
    if (c->number) {
        if (!((const uint8_t *)c->present.buf)[r])
            return NULL;
        char *end;
        if (c->number == 'i') {
            end = put_int(scratch, ((const int64_t *)c->view.buf)[r]);
        } else {
            float f = ((const float *)c->view.buf)[r];
            const char *word = isnan(f) ? "nan" : !isinf(f) ? NULL : f < 0 ? "-inf" : "inf";
            if (word != NULL) { /* as repr writes them */
                size_t len = strlen(word);
                memcpy(scratch, word, len);
                end = scratch + len;
            } else {
                end = ms_w_f32_repr(scratch, f);
            }
        }
        *n = end - scratch;
        return scratch;
    }
    int64_t id = c->have_view ? ((const int64_t *)c->view.buf)[r] : r;
    if (id < 0 || id >= PyList_GET_SIZE(c->list)) {
        PyErr_SetString(PyExc_ValueError, "join_fields: an id is out of the texts' range");
        *err = -1;
        return NULL;
    }
    PyObject *v = PyList_GET_ITEM(c->list, id);
    if (v == Py_None)
        return NULL;
    const char *s = PyUnicode_Check(v) ? PyUnicode_AsUTF8AndSize(v, n) : NULL;
    if (s == NULL) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_TypeError, "join_fields: a text is a str or None");
        *err = -1;
    }
    return s;
}

/* A coded column's cell for rows a..z (mode r, f, l or a); 0, or -1 with an exception set. */
static int put_coded(ms_buf *out, const column *c, int64_t a, int64_t z, char mode, char q, const char *agg,
                     Py_ssize_t agg_len) {
    int err = 0, any = 0;
    Py_ssize_t n;
    const char *s;
    char scratch[MS_DOUBLE_MAX];
    int64_t from = a, to = z, step = 1;
    if (mode == 'r')
        to = a + 1;
    else if (mode == 'l')
        from = z - 1, to = a - 1, step = -1;
    for (int64_t r = from; r != to; r += step) {
        s = coded_text(c, r, &n, &err, scratch);
        if (err)
            return -1;
        if (s == NULL)
            continue;
        if (!any && q)
            ms_buf_byte(out, q);
        else if (any)
            put_text(out, agg, agg_len, q);
        put_text(out, s, n, q);
        any = 1;
        if (mode != 'a')
            break;
    }
    if (any && q)
        ms_buf_byte(out, q);
    return 0;
}

/* A payload numbers column's buffers: float32 (`number` 'f') or int64 ('i') values, a byte per row for
 * present; 0, or -1 with an exception set (what was taken is kept in `c`, for release). */
static int number_views(column *c, PyObject *values, PyObject *present, char number) {
    if (number == 'i') {
        if (int64_view(values, &c->view) < 0)
            return -1;
        c->have_view = 1;
    } else {
        if (PyObject_GetBuffer(values, &c->view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
            return -1;
        c->have_view = 1;
        const char *f = c->view.format;
        if (c->view.itemsize != 4 || f == NULL || !(strcmp(f, "f") == 0 || strcmp(f, "<f") == 0 ||
                                                   strcmp(f, "=f") == 0)) {
            PyErr_SetString(PyExc_TypeError, "join_fields: f4 values are a float32 buffer");
            return -1;
        }
    }
    if (PyObject_GetBuffer(present, &c->present, PyBUF_C_CONTIGUOUS) < 0)
        return -1;
    c->have_present = 1;
    if (c->present.itemsize != 1) {
        PyErr_SetString(PyExc_TypeError, "join_fields: present is a byte per row");
        return -1;
    }
    c->number = number;
    return 0;
}

PyObject *ms_py_join_fields(PyObject *mod, PyObject *args) {
    (void)mod;
    PyObject *columns, *bounds_obj;
    const char *modes, *sep, *quote, *agg;
    Py_ssize_t modes_len, sep_len, quote_len, agg_len;
    if (!PyArg_ParseTuple(args, "O!Oy#s#s#s#", &PyList_Type, &columns, &bounds_obj, &modes, &modes_len, &sep,
                          &sep_len, &quote, &quote_len, &agg, &agg_len))
        return NULL;
    Py_ssize_t ncols = PyList_GET_SIZE(columns);
    if (quote_len > 1 || modes_len != ncols) {
        PyErr_SetString(PyExc_ValueError, "join_fields: the quote is one byte or none; a mode per column");
        return NULL;
    }
    Py_buffer bview;
    if (int64_view(bounds_obj, &bview) < 0)
        return NULL;
    const int64_t *bounds = bview.buf;
    Py_ssize_t groups = bview.len / 8 - 1;
    if (groups < 0)
        groups = 0;
    for (Py_ssize_t g = 0; g < groups; g++)
        if (bounds[g] < 0 || bounds[g + 1] <= bounds[g]) {
            PyBuffer_Release(&bview);
            PyErr_SetString(PyExc_ValueError, "join_fields: the bounds do not rise");
            return NULL;
        }
    column *cols = PyMem_Calloc(ncols ? (size_t)ncols : 1, sizeof(column));
    if (cols == NULL) {
        PyBuffer_Release(&bview);
        return PyErr_NoMemory();
    }
    for (Py_ssize_t k = 0; k < ncols; k++) {
        PyObject *c = PyList_GET_ITEM(columns, k);
        int bad;
        if (PyList_Check(c)) {
            cols[k].list = c;
            bad = PyList_GET_SIZE(c) != groups;
        } else if (PyTuple_Check(c) && PyTuple_GET_SIZE(c) == 3 && PyUnicode_Check(PyTuple_GET_ITEM(c, 0))) {
            const char *kind = PyUnicode_AsUTF8(PyTuple_GET_ITEM(c, 0));
            char number = kind == NULL ? 0 : strcmp(kind, "f4") == 0 ? 'f' : strcmp(kind, "i8") == 0 ? 'i' : 0;
            if (number == 0 || number_views(&cols[k], PyTuple_GET_ITEM(c, 1), PyTuple_GET_ITEM(c, 2), number) < 0) {
                if (!PyErr_Occurred())
                    PyErr_SetString(PyExc_TypeError, "join_fields: payload numbers are f4 or i8");
                release(cols, k + 1);
                PyBuffer_Release(&bview);
                return NULL;
            }
            cols[k].coded = 1;
            bad = groups > 0 && (cols[k].view.len / cols[k].view.itemsize < bounds[groups] ||
                                 cols[k].present.len < bounds[groups]);
        } else if (PyTuple_Check(c) && PyTuple_GET_SIZE(c) == 2 && PyList_Check(PyTuple_GET_ITEM(c, 0))) {
            cols[k].list = PyTuple_GET_ITEM(c, 0);
            cols[k].coded = 1;
            if (PyTuple_GET_ITEM(c, 1) == Py_None) { /* a value per row: the texts are the rows' */
                bad = groups > 0 && PyList_GET_SIZE(cols[k].list) < bounds[groups];
            } else {
                if (int64_view(PyTuple_GET_ITEM(c, 1), &cols[k].view) < 0) {
                    release(cols, k);
                    PyBuffer_Release(&bview);
                    return NULL;
                }
                cols[k].have_view = 1;
                bad = groups > 0 && cols[k].view.len / 8 < bounds[groups];
            }
        } else {
            if (int64_view(c, &cols[k].view) < 0) {
                release(cols, k);
                PyBuffer_Release(&bview);
                return NULL;
            }
            cols[k].have_view = 1;
            bad = groups > 0 && cols[k].view.len / 8 < bounds[groups];
        }
        if (!cols[k].list || cols[k].coded) /* a value per row: a mode picks or joins a record's */
            bad = bad || (modes[k] != 'r' && modes[k] != 'f' && modes[k] != 'l' && modes[k] != 'a');
        if (bad) {
            release(cols, k + 1);
            PyBuffer_Release(&bview);
            PyErr_SetString(PyExc_ValueError,
                            "join_fields: a column does not fit the bounds, or a mode is not r, f, l or a");
            return NULL;
        }
    }
    ms_buf out;
    ms_buf_init(&out);
    char q = quote_len ? quote[0] : 0;
    PyObject *text = NULL;
    for (Py_ssize_t g = 0; g < groups && !out.failed; g++) {
        for (Py_ssize_t k = 0; k < ncols; k++) {
            if (k)
                ms_buf_put(&out, sep, (size_t)sep_len);
            if (cols[k].coded) {
                if (put_coded(&out, &cols[k], bounds[g], bounds[g + 1], modes[k], q, agg, agg_len) < 0)
                    goto done;
                continue;
            }
            if (cols[k].list == NULL) {
                const int64_t *v = cols[k].view.buf;
                int64_t a = bounds[g], z = bounds[g + 1];
                if (q)
                    ms_buf_byte(&out, q);
                if (modes[k] == 'f' || modes[k] == 'r')
                    put_number(&out, v[a]);
                else if (modes[k] == 'l')
                    put_number(&out, v[z - 1]);
                else
                    for (int64_t r = a; r < z; r++) {
                        if (r > a)
                            put_text(&out, agg, agg_len, q);
                        put_number(&out, v[r]);
                    }
                if (q)
                    ms_buf_byte(&out, q);
                continue;
            }
            PyObject *v = PyList_GET_ITEM(cols[k].list, g);
            if (v == Py_None)
                continue;
            Py_ssize_t n;
            const char *s = PyUnicode_Check(v) ? PyUnicode_AsUTF8AndSize(v, &n) : NULL;
            if (s == NULL) {
                if (!PyErr_Occurred())
                    PyErr_SetString(PyExc_TypeError, "join_fields: a cell is a str or None");
                goto done;
            }
            if (q)
                ms_buf_byte(&out, q);
            put_text(&out, s, n, q);
            if (q)
                ms_buf_byte(&out, q);
        }
        ms_buf_byte(&out, '\n');
    }
    if (out.failed)
        PyErr_NoMemory();
    else
        text = PyUnicode_DecodeUTF8(out.data ? out.data : "", (Py_ssize_t)out.len, "strict");
done:
    ms_buf_free(&out);
    release(cols, ncols);
    PyBuffer_Release(&bview);
    return text;
}
