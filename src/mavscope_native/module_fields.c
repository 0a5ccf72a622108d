/* join_fields(columns, bounds, modes, separator, quote, aggregator) -> str: the lines of `read -T fields`.
 *
 * mavscope.output.fields_batch makes, per `-e` field, a column for the lines of whole records, line g being
 * the record of rows bounds[g]..bounds[g + 1] (an int64 buffer of G + 1 offsets): a list of G cells, each a
 * str or None (no value: an empty cell), or an int64 buffer (numpy) of header numbers, one per row, written
 * in decimal: the record's first (mode 'f'), last ('l') or all joined by `aggregator` ('a'; `modes` has a
 * byte per column). Line g is its cells joined by `separator`, each cell that has a value in `quote` (empty:
 * none) with a quote inside doubled, then "\n". The Python form (fields_batch.join_cells) is the reference:
 * tests/cli/test_fields_batch.py holds the two equal. */
#define PY_SSIZE_T_CLEAN
#include "module_fields.h"

#include <stdint.h>
#include <string.h>

#include "buf.h"

typedef struct {
    PyObject *list;  /* a list of str or None, or NULL for... */
    Py_buffer view;  /* ...an int64 buffer */
    int have_view;
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
    for (Py_ssize_t k = 0; k < n; k++)
        if (cols[k].have_view)
            PyBuffer_Release(&cols[k].view);
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
        } else {
            if (int64_view(c, &cols[k].view) < 0) {
                release(cols, k);
                PyBuffer_Release(&bview);
                return NULL;
            }
            cols[k].have_view = 1;
            bad = groups > 0 && cols[k].view.len / 8 < bounds[groups];
            bad = bad || (modes[k] != 'f' && modes[k] != 'l' && modes[k] != 'a');
        }
        if (bad) {
            release(cols, k + 1);
            PyBuffer_Release(&bview);
            PyErr_SetString(PyExc_ValueError,
                            "join_fields: a column does not fit the bounds, or a mode is not f, l or a");
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
            if (cols[k].list == NULL) {
                const int64_t *v = cols[k].view.buf;
                int64_t a = bounds[g], z = bounds[g + 1];
                if (q)
                    ms_buf_byte(&out, q);
                if (modes[k] == 'f')
                    put_number(&out, v[a]);
                else if (modes[k] == 'l')
                    put_number(&out, v[z - 1]);
                else
                    for (int64_t r = a; r < z; r++) {
                        if (r > a)
                            ms_buf_put(&out, agg, (size_t)agg_len);
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
            if (!q) {
                ms_buf_put(&out, s, (size_t)n);
                continue;
            }
            ms_buf_byte(&out, q);
            const char *at = s, *end = s + n, *hit;
            while ((hit = memchr(at, q, (size_t)(end - at))) != NULL) { /* a quote inside: doubled */
                ms_buf_put(&out, at, (size_t)(hit - at) + 1);
                ms_buf_byte(&out, q);
                at = hit + 1;
            }
            ms_buf_put(&out, at, (size_t)(end - at));
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
