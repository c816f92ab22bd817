/* deltagen/native/lean_ext.c: the CPython-extension entry of the single-row calls
 * (native/lean.py), one extension for every generated module, delta and serial.
 *
 * Why it exists (the target: one call from Python faster than pinocchio's rnea): a
 * cffi call of a kernel costs ~3 300 instructions, each (n,) input copied in through cffi
 * ~1 700 and the fresh output array ~2 300 (callgrind, Puma 560). Here the inputs are read
 * in place through the numpy C API, the kernel writes straight into the fresh output
 * array, and the only Python-level work left is the method call itself.
 *
 * kernel(fn, lead, geometry, n, inputs, scalar, out_shapes, ok, keep) -> a callable
 *   fn         the generated C function's address (cffi: int(ffi.cast("uintptr_t", f)))
 *   lead       0: an arm's  int fn(size_t rows, in..., out..., int8_t *status)
 *              1: the delta's int fn(const geometry *, size_t rows, size_t axes, in...,
 *                 out..., int8_t *status), called with axes = n
 *              2: a parameter struct without an axes count (the linear delta, the
 *                 tripod, the five-axis machine): int fn(const geometry *, size_t rows,
 *                 in..., out..., int8_t *status)
 *   geometry   the struct's address (the delta's geometry; 0 for an arm)
 *   n          the width of every input row (joints / drives)
 *   inputs     the number of (n,) rows (1..4)
 *   scalar     1: one more input, a Python float or int >= 0 (the delta's payload [kg]),
 *              passed as a const double * to one number
 *   out_shapes one shape (a tuple of at most 3 ints) per double output (1..3)
 *   ok         the status code of a row whose outputs are all finite (deltagen/status.py)
 *   keep       any object the function pointers depend on (the cffi module, the geometry
 *              struct's owner): held as long as the callable lives
 *
 * The callable takes the rows (and the scalar) positionally and returns a fresh float64
 * array (one output) or a tuple of them, or None when the general Python path must answer.
 * It accepts exactly what native/lean.py accepts (inputs.plain_row): a (n,) float64 ndarray
 * (exactly numpy.ndarray, native byte order; any strides: a strided or unaligned row is
 * gathered into a local buffer, as the general path's np.ascontiguousarray would) or a
 * list/tuple of n exact Python floats/ints. Anything else -- another shape, dtype or type,
 * an int beyond the float range, a wrong argument count, a negative or NaN scalar -- and
 * any status other than `ok` (a non-finite input is INVALID) returns None: the general
 * path then makes its checks and raises its errors, so both paths refuse the same input in
 * the same way. The same C function on the same numbers as the batch path: the same bits.
 *
 * The call keeps the GIL (a kernel of one row runs ~1 us; releasing and taking the GIL
 * back would cost more than it could give) and keeps no state between calls: every buffer
 * is on the C stack, so concurrent threads cannot see each other's numbers.
 *
 * Calling through a cast function pointer: the kernels' parameters are size_t, const
 * double *, double * and int8_t * (the delta's first one a pointer to its geometry struct);
 * the typedefs below spell exactly those, with the geometry as const void *.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

#include <math.h>
#include <stdint.h>
#include <string.h>

#ifndef DELTAGEN_LEAN_INIT /* the build names the init function after the cache key */
#define DELTAGEN_LEAN_INIT PyInit_deltagen_lean_ext
#define DELTAGEN_LEAN_NAME "deltagen_lean_ext"
#endif

#define MAX_WIDTH 64 /* joints per row: wider arms keep the Python lean path */
#define MAX_INPUTS 4
#define MAX_OUTPUTS 3
#define MAX_NDIM 3

typedef const double *In;
typedef double *Out;
typedef int8_t *Status;
typedef const void *Geometry;

typedef struct {
    PyObject_HEAD
    uintptr_t fn;
    int lead;
    Geometry geometry;
    Py_ssize_t n;
    int inputs;
    int scalar;
    int outputs;
    int ndim[MAX_OUTPUTS];
    npy_intp dims[MAX_OUTPUTS][MAX_NDIM];
    int ok;
    PyObject *keep;
} Spec;

static void spec_dealloc(Spec *self)
{
    Py_XDECREF(self->keep);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyTypeObject SpecType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "deltagen_lean_ext.Spec",
    .tp_basicsize = sizeof(Spec),
    .tp_dealloc = (destructor)spec_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "what a lean kernel call needs (function, shapes, status code)",
};

/* A row of n numbers from x: a pointer into x's own data when it is contiguous and
 * aligned, else the numbers gathered into buf. NULL when x is not what plain_row accepts
 * (no Python error is left set). */
static const double *read_row(PyObject *x, Py_ssize_t n, double *buf)
{
    if (Py_TYPE(x) == &PyArray_Type) {
        PyArrayObject *a = (PyArrayObject *)x;
        if (PyArray_NDIM(a) != 1 || PyArray_DIM(a, 0) != n || PyArray_TYPE(a) != NPY_DOUBLE
            || !PyArray_ISNOTSWAPPED(a))
            return NULL;
        const char *data = PyArray_BYTES(a);
        npy_intp stride = PyArray_STRIDE(a, 0);
        if (stride == (npy_intp)sizeof(double) && PyArray_ISALIGNED(a))
            return (const double *)data;
        for (Py_ssize_t i = 0; i < n; i++)
            memcpy(&buf[i], data + i * stride, sizeof(double));
        return buf;
    }
    if (PyList_CheckExact(x) || PyTuple_CheckExact(x)) {
        if (PySequence_Fast_GET_SIZE(x) != n)
            return NULL;
        PyObject **items = PySequence_Fast_ITEMS(x);
        for (Py_ssize_t i = 0; i < n; i++) {
            PyObject *v = items[i];
            if (PyFloat_CheckExact(v)) {
                buf[i] = PyFloat_AS_DOUBLE(v);
            } else if (PyLong_CheckExact(v)) { /* not bool: PyBool is a subtype */
                buf[i] = PyLong_AsDouble(v);
                if (buf[i] == -1.0 && PyErr_Occurred()) { /* beyond the float range */
                    PyErr_Clear();
                    return NULL;
                }
            } else {
                return NULL;
            }
        }
        return buf;
    }
    return NULL;
}

/* The scalar input (the delta's payload): an exact Python float or int >= 0. */
static int read_scalar(PyObject *x, double *value)
{
    if (PyFloat_CheckExact(x)) {
        *value = PyFloat_AS_DOUBLE(x);
    } else if (PyLong_CheckExact(x)) {
        *value = PyLong_AsDouble(x);
        if (*value == -1.0 && PyErr_Occurred()) {
            PyErr_Clear();
            return 0;
        }
    } else {
        return 0;
    }
    return *value >= 0.0; /* false for NaN too */
}

/* fn(lead..., in[0..k), out[0..m), status) for the k inputs and m outputs a kernel has. */
#define ARM_FN(...) ((int (*)(size_t, __VA_ARGS__, Status))spec->fn)
#define DELTA_FN(...) ((int (*)(Geometry, size_t, size_t, __VA_ARGS__, Status))spec->fn)
#define STRUCT_FN(...) ((int (*)(Geometry, size_t, __VA_ARGS__, Status))spec->fn)
#define KM(k, m) ((k) * 8 + (m))

static int call_arm(const Spec *spec, int k, In *in, Out *out, Status status)
{
    switch (KM(k, spec->outputs)) {
    case KM(1, 1): return ARM_FN(In, Out)(1, in[0], out[0], status);
    case KM(2, 1): return ARM_FN(In, In, Out)(1, in[0], in[1], out[0], status);
    case KM(3, 1): return ARM_FN(In, In, In, Out)(1, in[0], in[1], in[2], out[0], status);
    case KM(4, 1):
        return ARM_FN(In, In, In, In, Out)(1, in[0], in[1], in[2], in[3], out[0], status);
    case KM(1, 2): return ARM_FN(In, Out, Out)(1, in[0], out[0], out[1], status);
    case KM(2, 2): return ARM_FN(In, In, Out, Out)(1, in[0], in[1], out[0], out[1], status);
    default: return -1;
    }
}

static int call_delta(const Spec *spec, int k, In *in, Out *out, Status status)
{
    Geometry g = spec->geometry;
    size_t axes = (size_t)spec->n;
    switch (KM(k, spec->outputs)) {
    case KM(1, 1): return DELTA_FN(In, Out)(g, 1, axes, in[0], out[0], status);
    case KM(1, 2): return DELTA_FN(In, Out, Out)(g, 1, axes, in[0], out[0], out[1], status);
    case KM(2, 2):
        return DELTA_FN(In, In, Out, Out)(g, 1, axes, in[0], in[1], out[0], out[1], status);
    case KM(3, 3):
        return DELTA_FN(In, In, In, Out, Out, Out)(
            g, 1, axes, in[0], in[1], in[2], out[0], out[1], out[2], status);
    case KM(4, 1):
        return DELTA_FN(In, In, In, In, Out)(
            g, 1, axes, in[0], in[1], in[2], in[3], out[0], status);
    default: return -1;
    }
}

static int call_struct(const Spec *spec, int k, In *in, Out *out, Status status)
{
    Geometry g = spec->geometry;
    switch (KM(k, spec->outputs)) {
    case KM(1, 1): return STRUCT_FN(In, Out)(g, 1, in[0], out[0], status);
    case KM(1, 2): return STRUCT_FN(In, Out, Out)(g, 1, in[0], out[0], out[1], status);
    case KM(2, 2): return STRUCT_FN(In, In, Out, Out)(g, 1, in[0], in[1], out[0], out[1], status);
    case KM(3, 3):
        return STRUCT_FN(In, In, In, Out, Out, Out)(
            g, 1, in[0], in[1], in[2], out[0], out[1], out[2], status);
    case KM(4, 1):
        return STRUCT_FN(In, In, In, In, Out)(g, 1, in[0], in[1], in[2], in[3], out[0], status);
    default: return -1;
    }
}

static int supported(int lead, int k, int m)
{
    if (lead == 0)
        return KM(k, m) == KM(1, 1) || KM(k, m) == KM(2, 1) || KM(k, m) == KM(3, 1)
               || KM(k, m) == KM(4, 1) || KM(k, m) == KM(1, 2) || KM(k, m) == KM(2, 2);
    return KM(k, m) == KM(1, 1) || KM(k, m) == KM(1, 2) || KM(k, m) == KM(2, 2)
           || KM(k, m) == KM(3, 3) || KM(k, m) == KM(4, 1);
}

static PyObject *lean_call(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    const Spec *spec = (const Spec *)self;
    const Py_ssize_t n = spec->n;
    const int k = spec->inputs + spec->scalar;
    if (nargs != k)
        Py_RETURN_NONE;
    double buf[MAX_INPUTS][MAX_WIDTH];
    double scalar;
    In in[MAX_INPUTS];
    for (int i = 0; i < spec->inputs; i++) {
        in[i] = read_row(args[i], n, buf[i]);
        if (in[i] == NULL)
            Py_RETURN_NONE;
    }
    if (spec->scalar) {
        if (!read_scalar(args[spec->inputs], &scalar))
            Py_RETURN_NONE;
        in[spec->inputs] = &scalar;
    }
    PyObject *result[MAX_OUTPUTS] = {NULL, NULL, NULL};
    Out out[MAX_OUTPUTS];
    for (int j = 0; j < spec->outputs; j++) {
        result[j] = PyArray_SimpleNew(spec->ndim[j], (npy_intp *)spec->dims[j], NPY_DOUBLE);
        if (result[j] == NULL)
            goto fail;
        out[j] = (Out)PyArray_DATA((PyArrayObject *)result[j]);
    }
    int8_t status = -1;
    int rc = spec->lead == 0   ? call_arm(spec, k, in, out, &status)
             : spec->lead == 1 ? call_delta(spec, k, in, out, &status)
                               : call_struct(spec, k, in, out, &status);
    if (rc != 0 || status != spec->ok) { /* the general path reports it */
        for (int j = 0; j < spec->outputs; j++)
            Py_DECREF(result[j]);
        Py_RETURN_NONE;
    }
    if (spec->outputs == 1)
        return result[0];
    PyObject *tuple = PyTuple_New(spec->outputs);
    if (tuple == NULL)
        goto fail;
    for (int j = 0; j < spec->outputs; j++)
        PyTuple_SET_ITEM(tuple, j, result[j]); /* steals the reference */
    return tuple;
fail:
    for (int j = 0; j < spec->outputs; j++)
        Py_XDECREF(result[j]);
    return NULL;
}

static PyMethodDef call_def = {"lean_call", (PyCFunction)(void (*)(void))lean_call, METH_FASTCALL,
                               "one row of a generated kernel (deltagen/native/lean_ext.c)"};

static PyObject *kernel(PyObject *module, PyObject *args)
{
    (void)module;
    unsigned long long fn, geometry;
    int lead, inputs, scalar, ok;
    Py_ssize_t n;
    PyObject *shapes, *keep;
    if (!PyArg_ParseTuple(args, "KiKniiO!iO", &fn, &lead, &geometry, &n, &inputs, &scalar,
                          &PyTuple_Type, &shapes, &ok, &keep))
        return NULL;
    Py_ssize_t m = PyTuple_GET_SIZE(shapes);
    if (fn == 0 || lead < 0 || lead > 2 || (lead != 0 && geometry == 0) || n < 1
        || n > MAX_WIDTH || inputs < 1 || scalar < 0 || scalar > 1
        || inputs + scalar > MAX_INPUTS || m < 1 || m > MAX_OUTPUTS
        || !supported(lead, inputs + scalar, (int)m)) {
        PyErr_SetString(PyExc_ValueError, "lean_ext.kernel: a kernel form it does not serve");
        return NULL;
    }
    Spec *spec = PyObject_New(Spec, &SpecType);
    if (spec == NULL)
        return NULL;
    spec->fn = (uintptr_t)fn;
    spec->lead = lead;
    spec->geometry = (Geometry)(uintptr_t)geometry;
    spec->n = n;
    spec->inputs = inputs;
    spec->scalar = scalar;
    spec->outputs = (int)m;
    spec->ok = ok;
    Py_INCREF(keep);
    spec->keep = keep;
    for (Py_ssize_t j = 0; j < m; j++) {
        PyObject *shape = PyTuple_GET_ITEM(shapes, j);
        Py_ssize_t ndim = PyTuple_Check(shape) ? PyTuple_GET_SIZE(shape) : -1;
        if (ndim < 1 || ndim > MAX_NDIM) {
            PyErr_SetString(PyExc_ValueError, "lean_ext.kernel: each shape is 1 to 3 ints");
            Py_DECREF(spec);
            return NULL;
        }
        spec->ndim[j] = (int)ndim;
        for (Py_ssize_t d = 0; d < ndim; d++) {
            spec->dims[j][d] = (npy_intp)PyLong_AsSsize_t(PyTuple_GET_ITEM(shape, d));
            if (spec->dims[j][d] < 1) {
                if (!PyErr_Occurred())
                    PyErr_SetString(PyExc_ValueError, "lean_ext.kernel: a dimension < 1");
                Py_DECREF(spec);
                return NULL;
            }
        }
    }
    PyObject *call = PyCFunction_NewEx(&call_def, (PyObject *)spec, NULL);
    Py_DECREF(spec); /* the function holds it */
    return call;
}

/* ---- ik_all of one pose, with check_poses' rule in C (deltagen/solve/ik.py) ----
 *
 * pose_kernel(fn, k, n, answers, rigid_tol, bottom_tol, wrap, keep) -> callable(T)
 *   fn         int fn(size_t rows, const double *T, double *q, uint8_t *valid,
 *              int8_t *status): the generated closed-form ik_all (codegen/ik_kernel.py)
 *   k, n       branches and joints: q comes back (k, n) float64, valid (k,) bool
 *   answers    the status codes whose outputs are the answer as they stand (a tuple of
 *              ints: OK and UNREACHABLE; the batch path returns the same q and flags)
 *   rigid_tol, bottom_tol   check_poses' tolerances (solve/ik.py _RIGID_TOL, _BOTTOM_TOL)
 *   wrap       None: return the tuple (q, valid); else wrap((q, valid)) is returned
 *   keep       as kernel()'s
 *
 * The callable takes one (4, 4) float64 ndarray (exactly numpy.ndarray, native byte order,
 * any strides) and returns the answer, or None -- for any other argument, a pose that is
 * not finite or not a rigid transform, or a status not in `answers` -- so that the general
 * path makes its checks and raises or marks as it does for every other call. The rigidity
 * rule is check_one_pose's (solve/ik.py), written with the same operations in the same
 * order (ISO C99, no contraction into fused multiply-adds: the same roundings as Python's
 * floats): every entry finite; each row of the rotation block of unit length and the rows
 * pairwise orthogonal to rigid_tol; the bottom row 0 0 0 1 to bottom_tol. */

#define MAX_ANSWERS 4

typedef struct {
    PyObject_HEAD
    uintptr_t fn;
    npy_intp k, n;
    int answers[MAX_ANSWERS];
    int nanswers;
    double rigid_tol, bottom_tol;
    PyObject *wrap;
    PyObject *keep;
} PoseSpec;

static void pose_spec_dealloc(PoseSpec *self)
{
    Py_XDECREF(self->wrap);
    Py_XDECREF(self->keep);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyTypeObject PoseSpecType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "deltagen_lean_ext.PoseSpec",
    .tp_basicsize = sizeof(PoseSpec),
    .tp_dealloc = (destructor)pose_spec_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "what a one-pose ik_all call needs (function, shapes, answers, tolerances)",
};

/* 1 when the 16 entries (row by row) are finite and a rigid transform by check_one_pose's
 * rule, else 0. */
static int rigid_pose(const double *v, double tol, double bottom)
{
    for (int i = 0; i < 16; i++)
        if (!isfinite(v[i]))
            return 0;
    const double a = v[0], b = v[1], c = v[2], d = v[4], e = v[5], f = v[6];
    const double g = v[8], h = v[9], i = v[10];
    return fabs(a * a + b * b + c * c - 1.0) < tol && fabs(d * d + e * e + f * f - 1.0) < tol
           && fabs(g * g + h * h + i * i - 1.0) < tol && fabs(a * d + b * e + c * f) < tol
           && fabs(a * g + b * h + c * i) < tol && fabs(d * g + e * h + f * i) < tol
           && fabs(v[12]) < bottom && fabs(v[13]) < bottom && fabs(v[14]) < bottom
           && fabs(v[15] - 1.0) < bottom;
}

/* The 16 entries of a (4, 4) float64 ndarray in native byte order, row by row; 0 for any
 * other argument. */
static int read_pose(PyObject *x, double T[16])
{
    if (Py_TYPE(x) != &PyArray_Type)
        return 0;
    PyArrayObject *a = (PyArrayObject *)x;
    if (PyArray_NDIM(a) != 2 || PyArray_DIM(a, 0) != 4 || PyArray_DIM(a, 1) != 4
        || PyArray_TYPE(a) != NPY_DOUBLE || !PyArray_ISNOTSWAPPED(a))
        return 0;
    const char *data = PyArray_BYTES(a);
    const npy_intp s0 = PyArray_STRIDE(a, 0), s1 = PyArray_STRIDE(a, 1);
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++)
            memcpy(&T[4 * r + c], data + r * s0 + c * s1, sizeof(double));
    return 1;
}

typedef int (*PoseFn)(size_t, const double *, double *, uint8_t *, int8_t *);

static PyObject *pose_call(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    const PoseSpec *spec = (const PoseSpec *)self;
    double T[16];
    if (nargs != 1 || !read_pose(args[0], T))
        Py_RETURN_NONE;
    if (!rigid_pose(T, spec->rigid_tol, spec->bottom_tol))
        Py_RETURN_NONE; /* the general path: InputError, or NaN and invalid */
    npy_intp qdims[2] = {spec->k, spec->n};
    PyObject *q = PyArray_SimpleNew(2, qdims, NPY_DOUBLE);
    if (q == NULL)
        return NULL;
    PyObject *valid = PyArray_SimpleNew(1, (npy_intp *)&spec->k, NPY_BOOL);
    if (valid == NULL) {
        Py_DECREF(q);
        return NULL;
    }
    int8_t status = -1;
    int rc = ((PoseFn)spec->fn)(1, T, (double *)PyArray_DATA((PyArrayObject *)q),
                                (uint8_t *)PyArray_DATA((PyArrayObject *)valid), &status);
    int answer = 0;
    for (int j = 0; j < spec->nanswers; j++)
        answer |= status == spec->answers[j];
    if (rc != 0 || !answer) {
        Py_DECREF(q);
        Py_DECREF(valid);
        Py_RETURN_NONE;
    }
    PyObject *pair = PyTuple_New(2);
    if (pair == NULL) {
        Py_DECREF(q);
        Py_DECREF(valid);
        return NULL;
    }
    PyTuple_SET_ITEM(pair, 0, q); /* steals the references */
    PyTuple_SET_ITEM(pair, 1, valid);
    if (spec->wrap == Py_None)
        return pair;
    PyObject *wrapped = PyObject_CallOneArg(spec->wrap, pair);
    Py_DECREF(pair);
    return wrapped;
}

static PyMethodDef pose_call_def = {
    "pose_call", (PyCFunction)(void (*)(void))pose_call, METH_FASTCALL,
    "ik_all of one checked pose (deltagen/native/lean_ext.c)"};

static PyObject *pose_kernel(PyObject *module, PyObject *args)
{
    (void)module;
    unsigned long long fn;
    Py_ssize_t k, n;
    double rigid_tol, bottom_tol;
    PyObject *answers, *wrap, *keep;
    if (!PyArg_ParseTuple(args, "KnnO!ddOO", &fn, &k, &n, &PyTuple_Type, &answers, &rigid_tol,
                          &bottom_tol, &wrap, &keep))
        return NULL;
    Py_ssize_t m = PyTuple_GET_SIZE(answers);
    if (fn == 0 || k < 1 || n < 1 || n > MAX_WIDTH || m < 1 || m > MAX_ANSWERS
        || !(rigid_tol > 0.0) || !(bottom_tol > 0.0)
        || (wrap != Py_None && !PyCallable_Check(wrap))) {
        PyErr_SetString(PyExc_ValueError, "lean_ext.pose_kernel: a form it does not serve");
        return NULL;
    }
    PoseSpec *spec = PyObject_New(PoseSpec, &PoseSpecType);
    if (spec == NULL)
        return NULL;
    spec->fn = (uintptr_t)fn;
    spec->k = (npy_intp)k;
    spec->n = (npy_intp)n;
    spec->nanswers = (int)m;
    spec->rigid_tol = rigid_tol;
    spec->bottom_tol = bottom_tol;
    Py_INCREF(wrap);
    spec->wrap = wrap;
    Py_INCREF(keep);
    spec->keep = keep;
    for (Py_ssize_t j = 0; j < m; j++) {
        long code = PyLong_AsLong(PyTuple_GET_ITEM(answers, j));
        if (code == -1 && PyErr_Occurred()) {
            Py_DECREF(spec);
            return NULL;
        }
        spec->answers[j] = (int)code;
    }
    PyObject *call = PyCFunction_NewEx(&pose_call_def, (PyObject *)spec, NULL);
    Py_DECREF(spec); /* the function holds it */
    return call;
}

/* rigid_pose(T) -> bool: check_one_pose's rigid flag for one (4, 4) float64 ndarray (the
 * tolerances given), for the tests; None for any other argument. */
static PyObject *rigid_pose_py(PyObject *module, PyObject *args)
{
    (void)module;
    PyObject *x;
    double tol, bottom;
    if (!PyArg_ParseTuple(args, "Odd", &x, &tol, &bottom))
        return NULL;
    double T[16];
    if (!read_pose(x, T))
        Py_RETURN_NONE;
    return PyBool_FromLong(rigid_pose(T, tol, bottom));
}

/* ---- the numerical IK of one target (the runtime's deltagen_ik_newton.c) ----
 *
 * newton_kernel(fn, n, options, qlim, ok, keep) -> callable(T, q0)
 *   fn       int fn(size_t rows, const deltagen_ik_options *, const double *T,
 *            const double *q0, const double *qlim, double *q, double *err_p,
 *            double *err_r, int32_t *iterations, int8_t *status): <prefix>_ik_newton
 *   n        the joints
 *   options  the address of a filled deltagen_ik_options struct, qlim of the (n, 2)
 *            limits: both owned by `keep`, held as long as the callable lives
 *   ok       the status code of a converged row
 *
 * The callable takes T, a (4, 4) float64 ndarray (native byte order, any strides; the
 * caller has checked that it is a finite rigid transform), and q0 as read_row reads it,
 * and returns a fresh (n,) float64 q when the solver converged (status ok), else None (the
 * general path answers: its restarts, errors and messages). The same C function on the
 * same numbers as the cffi path (solve/numeric.py single_solver): the same bits. Unlike
 * the other entries it releases the GIL during the solve (as cffi does). */

typedef int (*NewtonFn)(size_t, const void *, const double *, const double *, const double *,
                        double *, double *, double *, int32_t *, int8_t *);

typedef struct {
    PyObject_HEAD
    uintptr_t fn;
    Py_ssize_t n;
    const void *options;
    const double *qlim;
    int ok;
    PyObject *keep;
} NewtonSpec;

static void newton_spec_dealloc(NewtonSpec *self)
{
    Py_XDECREF(self->keep);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyTypeObject NewtonSpecType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "deltagen_lean_ext.NewtonSpec",
    .tp_basicsize = sizeof(NewtonSpec),
    .tp_dealloc = (destructor)newton_spec_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "what a one-target numerical IK call needs (function, options, limits)",
};

/* The solve of newton_call on the pose T and the start in buf (n numbers, on the caller's
 * stack): a fresh q when the solver converged, else None (new references), NULL with an
 * exception set when q could not be made. */
static PyObject *newton_solve(const NewtonSpec *spec, const double T[16], const double *buf)
{
    npy_intp dims[1] = {(npy_intp)spec->n};
    PyObject *q = PyArray_SimpleNew(1, dims, NPY_DOUBLE);
    if (q == NULL)
        return NULL;
    double *q_out = (double *)PyArray_DATA((PyArrayObject *)q);
    double ep, er;
    int32_t iterations;
    int8_t status = -1;
    int rc;
    /* the solve takes microseconds to milliseconds: the GIL is released meanwhile, as the
     * cffi path releases it (every number it reads or writes is on this C stack or in q,
     * which no other thread has seen yet) */
    Py_BEGIN_ALLOW_THREADS
    rc = ((NewtonFn)spec->fn)(1, spec->options, T, buf, spec->qlim, q_out, &ep, &er,
                              &iterations, &status);
    Py_END_ALLOW_THREADS
    if (rc != 0 || status != spec->ok) {
        Py_DECREF(q);
        Py_RETURN_NONE;
    }
    return q;
}

static PyObject *newton_call(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    const NewtonSpec *spec = (const NewtonSpec *)self;
    double T[16], buf[MAX_WIDTH];
    if (nargs != 2 || !read_pose(args[0], T))
        Py_RETURN_NONE;
    const double *q0 = read_row(args[1], spec->n, buf);
    if (q0 == NULL)
        Py_RETURN_NONE;
    if (q0 != buf) /* the caller's array: copied, other threads run during the solve */
        memcpy(buf, q0, (size_t)spec->n * sizeof(double));
    return newton_solve(spec, T, buf);
}

static PyMethodDef newton_call_def = {
    "newton_call", (PyCFunction)(void (*)(void))newton_call, METH_FASTCALL,
    "the numerical IK of one target (deltagen/native/lean_ext.c)"};

static PyObject *newton_kernel(PyObject *module, PyObject *args)
{
    (void)module;
    unsigned long long fn, options, qlim;
    Py_ssize_t n;
    int ok;
    PyObject *keep;
    if (!PyArg_ParseTuple(args, "KnKKiO", &fn, &n, &options, &qlim, &ok, &keep))
        return NULL;
    if (fn == 0 || options == 0 || qlim == 0 || n < 1 || n > MAX_WIDTH) {
        PyErr_SetString(PyExc_ValueError, "lean_ext.newton_kernel: a form it does not serve");
        return NULL;
    }
    NewtonSpec *spec = PyObject_New(NewtonSpec, &NewtonSpecType);
    if (spec == NULL)
        return NULL;
    spec->fn = (uintptr_t)fn;
    spec->n = n;
    spec->options = (const void *)(uintptr_t)options;
    spec->qlim = (const double *)(uintptr_t)qlim;
    spec->ok = ok;
    Py_INCREF(keep);
    spec->keep = keep;
    PyObject *call = PyCFunction_NewEx(&newton_call_def, (PyObject *)spec, NULL);
    Py_DECREF(spec); /* the function holds it */
    return call;
}

/* ---- the cheap test of ik's exact-singularity check (solve/ik.py singular_one) ----
 *
 * regular_kernel(jacobian, lu, n, tol, ok, keep) -> callable(q)
 *   jacobian  int fn(size_t rows, const double *q, double *J, int8_t *status): the arm's
 *             generated geometric Jacobian, J (n x n) row-major (a square one: 6 joints)
 *   lu        the runtime's deltagen_lu (codegen/runtime/deltagen_linalg.c) in the same
 *             module: LU factorisation with partial pivoting, in place
 *   tol       status.SINGULAR_TOL
 *
 * The callable takes q as read_row reads it and returns True when |det J| >= tol |J|_F^n
 * (|J|_F >= sigma_max, so sigma_min / sigma_max >= tol: not singular), False when that
 * test does not clear q (the caller's SVD decides), None for any other argument or a
 * status other than ok. |det J| is the product of the magnitudes of U's diagonal. */

#define MAX_SQUARE 12

typedef int (*JacobianFn)(size_t, const double *, double *, int8_t *);
typedef int (*LuFn)(double *, size_t, int *, double *);

typedef struct {
    PyObject_HEAD
    uintptr_t jacobian, lu;
    Py_ssize_t n;
    double tol;
    int ok;
    PyObject *keep;
} RegularSpec;

static void regular_spec_dealloc(RegularSpec *self)
{
    Py_XDECREF(self->keep);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyTypeObject RegularSpecType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "deltagen_lean_ext.RegularSpec",
    .tp_basicsize = sizeof(RegularSpec),
    .tp_dealloc = (destructor)regular_spec_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "what the cheap singularity test needs (Jacobian, LU, tolerance)",
};

/* The cheap test on q (n numbers): 1 cleared (not singular), 0 not cleared (the caller's
 * SVD decides), -1 the Jacobian's status was not ok. */
static int regular_test(const RegularSpec *spec, const double *q)
{
    double J[MAX_SQUARE * MAX_SQUARE];
    int8_t status = -1;
    const size_t n = (size_t)spec->n;
    if (((JacobianFn)spec->jacobian)(1, q, J, &status) != 0 || status != spec->ok)
        return -1;
    double frobenius = 0.0;
    for (size_t i = 0; i < n * n; i++)
        frobenius += J[i] * J[i];
    frobenius = sqrt(frobenius);
    if (((LuFn)spec->lu)(J, n, NULL, NULL) != 0)
        return 0; /* a zero pivot: the SVD decides */
    double det = 1.0;
    for (size_t i = 0; i < n; i++)
        det *= fabs(J[i * n + i]);
    return det >= spec->tol * pow(frobenius, (double)n);
}

static PyObject *regular_call(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    const RegularSpec *spec = (const RegularSpec *)self;
    double buf[MAX_WIDTH];
    if (nargs != 1)
        Py_RETURN_NONE;
    const double *q = read_row(args[0], spec->n, buf);
    if (q == NULL)
        Py_RETURN_NONE;
    const int cleared = regular_test(spec, q);
    if (cleared < 0)
        Py_RETURN_NONE;
    return PyBool_FromLong(cleared);
}

static PyMethodDef regular_call_def = {
    "regular_call", (PyCFunction)(void (*)(void))regular_call, METH_FASTCALL,
    "the cheap singularity test of one configuration (deltagen/native/lean_ext.c)"};

static PyObject *regular_kernel(PyObject *module, PyObject *args)
{
    (void)module;
    unsigned long long jacobian, lu;
    Py_ssize_t n;
    double tol;
    int ok;
    PyObject *keep;
    if (!PyArg_ParseTuple(args, "KKndiO", &jacobian, &lu, &n, &tol, &ok, &keep))
        return NULL;
    if (jacobian == 0 || lu == 0 || n < 1 || n > MAX_SQUARE || !(tol > 0.0)) {
        PyErr_SetString(PyExc_ValueError, "lean_ext.regular_kernel: a form it does not serve");
        return NULL;
    }
    RegularSpec *spec = PyObject_New(RegularSpec, &RegularSpecType);
    if (spec == NULL)
        return NULL;
    spec->jacobian = (uintptr_t)jacobian;
    spec->lu = (uintptr_t)lu;
    spec->n = n;
    spec->tol = tol;
    spec->ok = ok;
    Py_INCREF(keep);
    spec->keep = keep;
    PyObject *call = PyCFunction_NewEx(&regular_call_def, (PyObject *)spec, NULL);
    Py_DECREF(spec); /* the function holds it */
    return call;
}

/* ---- numeric ik of one pose in one call: the pose's check, the solve and the cheap
 * singularity test (solve/ik.py IKPlanner.lean_numeric, SerialRobot.ik) ----
 *
 * ik_one_kernel(newton, regular, q0, rigid_tol, bottom_tol) -> callable(T)
 *   newton    a callable made by newton_kernel (its function, options and limits serve)
 *   regular   a callable made by regular_kernel for the same arm, or None (no test:
 *             singular="allow")
 *   q0        the start, an (n,) float64 array (its numbers are copied here)
 *   rigid_tol, bottom_tol   check_poses' tolerances, as pose_kernel's
 *
 * The callable takes T as pose_call reads it and makes, in C, what the Python one-pose path
 * makes in three calls, with the same functions on the same numbers (the same bits):
 * rigid_pose (check_one_pose's rule), newton_call's solve from q0 and regular_call's test
 * of the converged q. It returns q when the solver converged and the test cleared q (or
 * there is no test); the tuple (q,) when it converged but the test did not clear q (the
 * caller's singularity check decides); None for a pose that is not a finite rigid
 * transform, or no convergence (the general path answers; the one-pose path need not be
 * tried again); False for any other argument (not one pose it reads: the caller's other
 * paths take it). */

typedef struct {
    PyObject_HEAD
    PyObject *newton, *regular; /* the callables; their specs below */
    const NewtonSpec *newton_spec;
    const RegularSpec *regular_spec; /* NULL: no test */
    double q0[MAX_WIDTH];
    double rigid_tol, bottom_tol;
} IkOneSpec;

static void ik_one_spec_dealloc(IkOneSpec *self)
{
    Py_XDECREF(self->newton);
    Py_XDECREF(self->regular);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyTypeObject IkOneSpecType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "deltagen_lean_ext.IkOneSpec",
    .tp_basicsize = sizeof(IkOneSpec),
    .tp_dealloc = (destructor)ik_one_spec_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "what numeric ik of one pose needs (the solver's and the test's specs, q0)",
};

static PyObject *ik_one_call(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    const IkOneSpec *spec = (const IkOneSpec *)self;
    double T[16], buf[MAX_WIDTH];
    if (nargs != 1 || !read_pose(args[0], T))
        Py_RETURN_FALSE;
    if (!rigid_pose(T, spec->rigid_tol, spec->bottom_tol))
        Py_RETURN_NONE;
    memcpy(buf, spec->q0, (size_t)spec->newton_spec->n * sizeof(double));
    PyObject *q = newton_solve(spec->newton_spec, T, buf);
    if (q == NULL || q == Py_None || spec->regular_spec == NULL)
        return q;
    if (regular_test(spec->regular_spec, (const double *)PyArray_DATA((PyArrayObject *)q)) == 1)
        return q;
    PyObject *undecided = PyTuple_New(1);
    if (undecided == NULL) {
        Py_DECREF(q);
        return NULL;
    }
    PyTuple_SET_ITEM(undecided, 0, q); /* steals the reference */
    return undecided;
}

static PyMethodDef ik_one_call_def = {
    "ik_one_call", (PyCFunction)(void (*)(void))ik_one_call, METH_FASTCALL,
    "numeric ik of one pose: check, solve, singularity test (deltagen/native/lean_ext.c)"};

/* The spec behind a callable that `def` made, or NULL. */
static PyObject *spec_of(PyObject *callable, const PyMethodDef *def)
{
    if (!PyCFunction_Check(callable)
        || PyCFunction_GET_FUNCTION(callable) != def->ml_meth)
        return NULL;
    return PyCFunction_GET_SELF(callable);
}

static PyObject *ik_one_kernel(PyObject *module, PyObject *args)
{
    (void)module;
    PyObject *newton, *regular, *q0;
    double rigid_tol, bottom_tol;
    if (!PyArg_ParseTuple(args, "OOOdd", &newton, &regular, &q0, &rigid_tol, &bottom_tol))
        return NULL;
    const NewtonSpec *newton_spec = (const NewtonSpec *)spec_of(newton, &newton_call_def);
    const RegularSpec *regular_spec =
        regular == Py_None ? NULL : (const RegularSpec *)spec_of(regular, &regular_call_def);
    double buf[MAX_WIDTH];
    const double *start = newton_spec == NULL ? NULL : read_row(q0, newton_spec->n, buf);
    if (newton_spec == NULL || (regular != Py_None && regular_spec == NULL)
        || (regular_spec != NULL && regular_spec->n != newton_spec->n) || start == NULL
        || !(rigid_tol > 0.0) || !(bottom_tol > 0.0)) {
        PyErr_SetString(PyExc_ValueError, "lean_ext.ik_one_kernel: a form it does not serve");
        return NULL;
    }
    IkOneSpec *spec = PyObject_New(IkOneSpec, &IkOneSpecType);
    if (spec == NULL)
        return NULL;
    Py_INCREF(newton);
    spec->newton = newton;
    Py_XINCREF(regular_spec == NULL ? NULL : regular);
    spec->regular = regular_spec == NULL ? NULL : regular;
    spec->newton_spec = newton_spec;
    spec->regular_spec = regular_spec;
    memcpy(spec->q0, start, (size_t)newton_spec->n * sizeof(double));
    spec->rigid_tol = rigid_tol;
    spec->bottom_tol = bottom_tol;
    PyObject *call = PyCFunction_NewEx(&ik_one_call_def, (PyObject *)spec, NULL);
    Py_DECREF(spec); /* the function holds it */
    return call;
}

static PyMethodDef methods[] = {
    {"kernel", kernel, METH_VARARGS,
     "kernel(fn, lead, geometry, n, inputs, scalar, out_shapes, ok, keep) -> callable"},
    {"pose_kernel", pose_kernel, METH_VARARGS,
     "pose_kernel(fn, k, n, answers, rigid_tol, bottom_tol, wrap, keep) -> callable"},
    {"newton_kernel", newton_kernel, METH_VARARGS,
     "newton_kernel(fn, n, options, qlim, ok, keep) -> callable(T, q0)"},
    {"regular_kernel", regular_kernel, METH_VARARGS,
     "regular_kernel(jacobian, lu, n, tol, ok, keep) -> callable(q)"},
    {"ik_one_kernel", ik_one_kernel, METH_VARARGS,
     "ik_one_kernel(newton, regular, q0, rigid_tol, bottom_tol) -> callable(T)"},
    {"rigid_pose", rigid_pose_py, METH_VARARGS,
     "rigid_pose(T, rigid_tol, bottom_tol) -> the rigid flag of check_one_pose"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT, DELTAGEN_LEAN_NAME,
    "single-row entry of the generated kernels (deltagen/native/lean_ext.c)", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC DELTAGEN_LEAN_INIT(void)
{
    import_array();
    if (PyType_Ready(&SpecType) < 0 || PyType_Ready(&PoseSpecType) < 0
        || PyType_Ready(&NewtonSpecType) < 0
        || PyType_Ready(&RegularSpecType) < 0 || PyType_Ready(&IkOneSpecType) < 0)
        return NULL;
    return PyModule_Create(&module_def);
}
