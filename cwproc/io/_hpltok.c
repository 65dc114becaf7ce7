/*
 * Whitespace tokenizer of the data lines of Halo .hpl files (cwproc.io.halo).
 *
 * tokenize(body: bytes, n_fields: int) -> (values: bytearray, n_lines: int, bad_line: int)
 *
 * values holds n_lines * n_fields native doubles (row major): the fields of every line,
 * NaN where a line has fewer fields, +inf where a field is not a decimal number
 * ("abc", "nan", "inf", "1.2.3"). Lines end at LF, CRLF or a lone CR; a final line
 * without its end counts, an empty body has no lines; a blank line is a row of NaN.
 * Fields are separated by runs of spaces and TABs. bad_line is the 0-based index of
 * the first line with more than n_fields fields (-1 if none); parsing stops there.
 *
 * tokenize_lines(body, n_fields, n_lines) is the same for a body whose lines the caller
 * has counted (the plan of a .hpl file): the counting pass is skipped. It returns
 * n_lines lines when the body has exactly that many, else a count that differs from
 * n_lines (n_lines + 1 for more lines), with values then incomplete: the caller takes
 * the file's reference path. Both release the GIL while they count and parse.
 *
 * first_bad_row(values, n_lines, n_fields, n_gates, ray_fields, gate_fields) -> int
 * checks the ray/gate block structure of a parsed table (values as tokenize returns
 * them): the index of the first line that breaks it, or -1. Line k is a ray line when
 * k is a multiple of n_gates + 1, else a gate line; its first ray_fields (gate_fields)
 * fields must be finite and the others NaN, and a gate line's first field must equal
 * its position in the block less one (its gate index). An incomplete last block is
 * checked as far as it goes. This is cwproc.io.halo_body.first_bad_row in one pass,
 * without the GIL (the numpy version makes about twenty passes, each taking the GIL
 * back when done).
 *
 * count_byte(data, end, byte) -> int: how often the byte occurs in data[:end]
 * (memchr, without the GIL).
 *
 * Numbers: [+-]digits[.digits][(e|E)[+-]digits]. With at most 19 significant digits
 * and a decimal exponent within +-22 the value is m * 10^e or m / 10^-e computed in
 * double precision from an exact integer m < 2^53 and an exact power of ten, which is
 * correctly rounded (Clinger (1990), "How to read floating point numbers accurately",
 * the fast path); any other number goes through PyOS_string_to_double (correctly
 * rounded, locale independent). Every result therefore equals float(token).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

static const double POW10[23] = {
    1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
    1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

/* Parse [p, end) as a whole decimal number; returns 0 and sets *out, or -1 (no number). */
static int parse_number(const char *p, const char *end, double *out)
{
    const char *start = p;
    int negative = 0;
    uint64_t mantissa = 0;
    int digits = 0, significant = 0, frac_digits = 0, dropped = 0, truncated = 0;
    long exponent = 0;

    if (p < end && (*p == '+' || *p == '-')) {
        negative = (*p == '-');
        p++;
    }
    while (p < end && *p >= '0' && *p <= '9') {
        if (significant < 19) {
            mantissa = mantissa * 10 + (uint64_t)(*p - '0');
            if (mantissa) significant++;
        } else {
            dropped++;
            truncated |= (*p != '0');
        }
        digits++;
        p++;
    }
    if (p < end && *p == '.') {
        p++;
        while (p < end && *p >= '0' && *p <= '9') {
            if (significant < 19) {
                mantissa = mantissa * 10 + (uint64_t)(*p - '0');
                if (mantissa) significant++;
                frac_digits++;
            } else {
                truncated |= (*p != '0');
            }
            digits++;
            p++;
        }
    }
    if (digits == 0) return -1;
    if (p < end && (*p == 'e' || *p == 'E')) {
        int exp_negative = 0, exp_digits = 0;
        p++;
        if (p < end && (*p == '+' || *p == '-')) {
            exp_negative = (*p == '-');
            p++;
        }
        while (p < end && *p >= '0' && *p <= '9') {
            if (exponent < 100000) exponent = exponent * 10 + (*p - '0');
            exp_digits++;
            p++;
        }
        if (exp_digits == 0) return -1;
        if (exp_negative) exponent = -exponent;
    }
    if (p != end) return -1;

    long e10 = exponent - frac_digits + dropped;
    if (!truncated && mantissa <= (UINT64_C(1) << 53) && e10 >= -22 && e10 <= 22) {
        double value = (double)mantissa;
        value = e10 < 0 ? value / POW10[-e10] : value * POW10[e10];
        *out = negative ? -value : value;
        return 0;
    }
    /* slow path: correctly rounded conversion of the token by Python (with the GIL) */
    {
        Py_ssize_t n = end - start;
        char *buffer = (char *)PyMem_RawMalloc((size_t)n + 1);
        char *stop = NULL;
        double value;
        int ok;
        if (buffer == NULL) return -1;
        memcpy(buffer, start, (size_t)n);
        buffer[n] = '\0';
        PyGILState_STATE gil = PyGILState_Ensure();
        value = PyOS_string_to_double(buffer, &stop, NULL);
        ok = !(value == -1.0 && PyErr_Occurred()) && stop == buffer + n;
        if (PyErr_Occurred()) PyErr_Clear();
        PyGILState_Release(gil);
        PyMem_RawFree(buffer);
        if (!ok) return -1;
        *out = value;
        return 0;
    }
}

/* Parse the lines of [data, end) into values (n_lines rows of n_fields): returns the
   number of lines parsed; *bad_line is set to the first line with too many fields. Stops
   after n_lines lines or at the end of the data, whichever comes first. No Python API
   (runs without the GIL). */
static Py_ssize_t parse_lines(const char *data, const char *end, double *values,
                              Py_ssize_t n_lines, int n_fields, Py_ssize_t *bad_line)
{
    const double nan = Py_NAN, inf = Py_HUGE_VAL;
    Py_ssize_t line = 0;
    const char *p = data;
    *bad_line = -1;
    while (line < n_lines && p < end) {
        double *row = values + line * n_fields;
        int field = 0;
        for (int k = 0; k < n_fields; k++) row[k] = nan;
        for (;;) {
            while (p < end && (*p == ' ' || *p == '\t')) p++;
            if (p >= end || *p == '\n' || *p == '\r') break;
            const char *token = p;
            while (p < end && *p != ' ' && *p != '\t' && *p != '\n' && *p != '\r') p++;
            if (field >= n_fields) {
                *bad_line = line;
                return line;
            }
            double value;
            row[field++] = parse_number(token, p, &value) == 0 ? value : inf;
        }
        if (p < end) {
            if (*p == '\r' && p + 1 < end && p[1] == '\n') p++;
            p++;
        }
        line++;
    }
    /* more lines than n_lines: report one more (the caller compares the count) */
    return (line == n_lines && p < end) ? n_lines + 1 : line;
}

/* Lines of [data, end): LF, CRLF or lone CR end a line; a final unterminated line
   counts. No Python API. */
static Py_ssize_t count_lines(const char *data, const char *end)
{
    Py_ssize_t n_lines = 0;
    for (const char *p = data; p < end; p++) {
        if (*p == '\n') {
            n_lines++;
        } else if (*p == '\r') {
            n_lines++;
            if (p + 1 < end && p[1] == '\n') p++;
        }
    }
    if (end > data && end[-1] != '\n' && end[-1] != '\r') n_lines++;
    return n_lines;
}

static PyObject *tokenize_impl(PyObject *args, int known)
{
    Py_buffer view;
    int n_fields;
    Py_ssize_t n_lines = 0;
    if (known) {
        if (!PyArg_ParseTuple(args, "y*in", &view, &n_fields, &n_lines)) return NULL;
    } else if (!PyArg_ParseTuple(args, "y*i", &view, &n_fields)) {
        return NULL;
    }
    if (n_fields < 1 || n_fields > 64 || n_lines < 0) {
        PyBuffer_Release(&view);
        PyErr_SetString(PyExc_ValueError, "n_fields must be in 1..64 and n_lines >= 0");
        return NULL;
    }
    const char *data = (const char *)view.buf;
    const char *end = data + view.len;

    if (!known) {
        Py_BEGIN_ALLOW_THREADS
        n_lines = count_lines(data, end);
        Py_END_ALLOW_THREADS
    }
    PyObject *out = PyByteArray_FromStringAndSize(
        NULL, (Py_ssize_t)(n_lines * n_fields * (Py_ssize_t)sizeof(double)));
    if (out == NULL) {
        PyBuffer_Release(&view);
        return NULL;
    }
    double *values = (double *)PyByteArray_AS_STRING(out);
    Py_ssize_t got, bad_line;

    Py_BEGIN_ALLOW_THREADS
    got = parse_lines(data, end, values, n_lines, n_fields, &bad_line);
    Py_END_ALLOW_THREADS

    PyBuffer_Release(&view);
    return Py_BuildValue("(Nnn)", out, bad_line >= 0 ? bad_line : got, bad_line);
}

static PyObject *tokenize(PyObject *self, PyObject *args) { return tokenize_impl(args, 0); }

static PyObject *tokenize_lines(PyObject *self, PyObject *args)
{
    return tokenize_impl(args, 1);
}

/* First line of a parsed table that breaks the block structure, or -1 (see the top). No
   Python API. */
static Py_ssize_t check_blocks(const double *values, Py_ssize_t n_lines, int n_fields,
                               Py_ssize_t n_gates, int ray_fields, int gate_fields)
{
    const Py_ssize_t block = n_gates + 1;
    for (Py_ssize_t line = 0; line < n_lines; line++) {
        const double *row = values + line * n_fields;
        const Py_ssize_t position = line % block;
        const int present = position == 0 ? ray_fields : gate_fields;
        for (int k = 0; k < n_fields; k++) {
            if (k < present ? !isfinite(row[k]) : !isnan(row[k])) return line;
        }
        if (position > 0 && row[0] != (double)(position - 1)) return line;
    }
    return -1;
}

static PyObject *first_bad_row(PyObject *self, PyObject *args)
{
    Py_buffer view;
    Py_ssize_t n_lines, n_gates;
    int n_fields, ray_fields, gate_fields;
    if (!PyArg_ParseTuple(args, "y*ninii", &view, &n_lines, &n_fields, &n_gates, &ray_fields,
                          &gate_fields))
        return NULL;
    if (n_fields < 1 || n_lines < 0 || n_gates < 0 || ray_fields < 0 || gate_fields < 0 ||
        view.len < n_lines * n_fields * (Py_ssize_t)sizeof(double)) {
        PyBuffer_Release(&view);
        PyErr_SetString(PyExc_ValueError, "values hold fewer than n_lines * n_fields doubles");
        return NULL;
    }
    Py_ssize_t bad;
    Py_BEGIN_ALLOW_THREADS
    bad = check_blocks((const double *)view.buf, n_lines, n_fields, n_gates, ray_fields,
                       gate_fields);
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&view);
    return PyLong_FromSsize_t(bad);
}

static PyObject *count_byte(PyObject *self, PyObject *args)
{
    Py_buffer view;
    Py_ssize_t end;
    int byte;
    if (!PyArg_ParseTuple(args, "y*ni", &view, &end, &byte)) return NULL;
    if (end < 0 || end > view.len || byte < 0 || byte > 255) {
        PyBuffer_Release(&view);
        PyErr_SetString(PyExc_ValueError, "end must be in 0..len(data) and byte in 0..255");
        return NULL;
    }
    Py_ssize_t count = 0;
    Py_BEGIN_ALLOW_THREADS
    const char *p = (const char *)view.buf, *stop = p + end;
    while (p < stop && (p = memchr(p, byte, (size_t)(stop - p))) != NULL) {
        count++;
        p++;
    }
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&view);
    return PyLong_FromSsize_t(count);
}

static PyMethodDef methods[] = {
    {"tokenize", tokenize, METH_VARARGS,
     "tokenize(body, n_fields) -> (values bytearray of doubles, n_lines, bad_line)"},
    {"tokenize_lines", tokenize_lines, METH_VARARGS,
     "tokenize_lines(body, n_fields, n_lines) -> as tokenize, for a body of n_lines lines "
     "(any other count is returned as n_lines + 1 or fewer; values then incomplete)"},
    {"first_bad_row", first_bad_row, METH_VARARGS,
     "first_bad_row(values, n_lines, n_fields, n_gates, ray_fields, gate_fields) -> first "
     "line breaking the ray/gate block structure, or -1"},
    {"count_byte", count_byte, METH_VARARGS,
     "count_byte(data, end, byte) -> occurrences of byte in data[:end]"},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_hpltok",
                                    "Tokenizer of .hpl data lines (see the C source).", -1,
                                    methods};

PyMODINIT_FUNC PyInit__hpltok(void) { return PyModule_Create(&module); }
