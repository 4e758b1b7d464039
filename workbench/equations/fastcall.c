/* A direct call from Python into a CasADi-generated C function (workbench.equations.fastcall).

   Caller(address, inputs, outputs, work, result, fallback) is a callable taking the
   function's inputs positionally: a float (one-element input) or a C-contiguous buffer of
   float64 of the input's length is copied into the preallocated input array, then the
   generated symbol at `address` runs on the bound arrays and `result` (the output views)
   is returned. Anything else (keywords, other counts, types, shapes) goes to
   `fallback(*args)` unchanged, so errors and conversions stay NumPy's. `calls` counts the
   direct calls. No NumPy headers: arrays are reached through the buffer protocol. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stddef.h>
#include <string.h>

typedef long long casadi_int;
typedef int (*casadi_function)(const double **arg, double **res, casadi_int *iw, double *w,
                               int mem);

typedef struct {
    PyObject_HEAD
    vectorcallfunc vectorcall;
    casadi_function function;
    int mem;
    Py_ssize_t n_in, n_out;
    Py_buffer *views;   /* n_in + n_out views held: the arrays cannot be resized */
    Py_ssize_t *sizes;  /* each input's number of doubles */
    const double **arg; /* sz_arg pointers, the first n_in the inputs */
    double **res;       /* sz_res pointers, the first n_out the outputs */
    casadi_int *iw;
    double *w;
    PyObject *result;
    PyObject *fallback;
    unsigned long long calls;
} Caller;

static PyObject *Caller_vectorcall(PyObject *callable, PyObject *const *args, size_t nargsf,
                                   PyObject *kwnames) {
    Caller *self = (Caller *)callable;
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    if (kwnames != NULL || nargs != self->n_in) goto general;
    for (Py_ssize_t i = 0; i < nargs; i++) {
        double *into = (double *)self->views[i].buf;
        PyObject *value = args[i];
        if (PyFloat_Check(value)) {
            if (self->sizes[i] != 1) goto general;
            into[0] = PyFloat_AS_DOUBLE(value);
            continue;
        }
        Py_buffer view;
        if (!PyObject_CheckBuffer(value) ||
            PyObject_GetBuffer(value, &view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) {
            PyErr_Clear();
            goto general;
        }
        int fits = view.itemsize == 8 && view.format != NULL &&
                   (strcmp(view.format, "d") == 0 || strcmp(view.format, "<d") == 0 ||
                    strcmp(view.format, "=d") == 0) &&
                   view.len == self->sizes[i] * 8;
        if (fits) memmove(into, view.buf, (size_t)view.len);
        PyBuffer_Release(&view);
        if (!fits) goto general;
    }
    if (self->function(self->arg, self->res, self->iw, self->w, self->mem) != 0) {
        PyErr_SetString(PyExc_RuntimeError, "the compiled function returned an error");
        return NULL;
    }
    self->calls++;
    Py_INCREF(self->result);
    return self->result;
general:
    if (self->fallback == NULL) {
        PyErr_SetString(PyExc_RuntimeError, "the caller was cleared");
        return NULL;
    }
    return PyObject_Vectorcall(self->fallback, args, nargsf, kwnames);
}

/* The fallback is usually a bound method of the object holding this caller: a cycle the
   garbage collector must see through. */
static int Caller_traverse(Caller *self, visitproc visit, void *arg) {
    Py_VISIT(self->result);
    Py_VISIT(self->fallback);
    return 0;
}

static int Caller_clear(Caller *self) {
    Py_CLEAR(self->result);
    Py_CLEAR(self->fallback);
    return 0;
}

static void Caller_dealloc(Caller *self) {
    PyObject_GC_UnTrack(self);
    Caller_clear(self);
    if (self->views != NULL) {
        for (Py_ssize_t i = 0; i < self->n_in + self->n_out; i++)
            if (self->views[i].obj != NULL) PyBuffer_Release(&self->views[i]);
    }
    PyMem_Free(self->views);
    PyMem_Free(self->sizes);
    PyMem_Free(self->arg);
    PyMem_Free(self->res);
    PyMem_Free(self->iw);
    PyMem_Free(self->w);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int hold(PyObject *sequence, Py_buffer *views, Py_ssize_t n) {
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *array = PyTuple_GET_ITEM(sequence, i);
        if (PyObject_GetBuffer(array, &views[i], PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE |
                                                     PyBUF_FORMAT) < 0)
            return -1;
        if (views[i].itemsize != 8 || strchr(views[i].format, 'd') == NULL) {
            PyErr_SetString(PyExc_TypeError, "arrays must be float64");
            return -1;
        }
    }
    return 0;
}

static PyObject *Caller_new(PyTypeObject *type, PyObject *args, PyObject *kwds) {
    unsigned long long address;
    int mem;
    PyObject *inputs, *outputs, *result, *fallback;
    Py_ssize_t sz_arg, sz_res, sz_iw, sz_w;
    if (!PyArg_ParseTuple(args, "KiO!O!(nnnn)OO", &address, &mem, &PyTuple_Type, &inputs,
                          &PyTuple_Type, &outputs, &sz_arg, &sz_res, &sz_iw, &sz_w, &result,
                          &fallback))
        return NULL;
    Py_ssize_t n_in = PyTuple_GET_SIZE(inputs), n_out = PyTuple_GET_SIZE(outputs);
    if (address == 0 || sz_arg < n_in || sz_res < n_out || sz_iw < 0 || sz_w < 0) {
        PyErr_SetString(PyExc_ValueError, "bad address or work sizes");
        return NULL;
    }
    Caller *self = (Caller *)type->tp_alloc(type, 0);
    if (self == NULL) return NULL;
    self->vectorcall = Caller_vectorcall;
    self->function = (casadi_function)(uintptr_t)address;
    self->mem = mem;
    self->n_in = n_in;
    self->n_out = n_out;
    Py_INCREF(result);
    self->result = result;
    Py_INCREF(fallback);
    self->fallback = fallback;
    self->views = PyMem_Calloc((size_t)(n_in + n_out) + 1, sizeof(Py_buffer));
    self->sizes = PyMem_Calloc((size_t)n_in + 1, sizeof(Py_ssize_t));
    self->arg = PyMem_Calloc((size_t)sz_arg + 1, sizeof(double *));
    self->res = PyMem_Calloc((size_t)sz_res + 1, sizeof(double *));
    self->iw = PyMem_Calloc((size_t)sz_iw + 1, sizeof(casadi_int));
    self->w = PyMem_Calloc((size_t)sz_w + 1, sizeof(double));
    if (!self->views || !self->sizes || !self->arg || !self->res || !self->iw || !self->w) {
        Py_DECREF(self);
        return PyErr_NoMemory();
    }
    if (hold(inputs, self->views, n_in) < 0 || hold(outputs, self->views + n_in, n_out) < 0) {
        Py_DECREF(self);
        return NULL;
    }
    for (Py_ssize_t i = 0; i < n_in; i++) {
        self->sizes[i] = self->views[i].len / 8;
        self->arg[i] = (const double *)self->views[i].buf;
    }
    for (Py_ssize_t i = 0; i < n_out; i++) self->res[i] = (double *)self->views[n_in + i].buf;
    return (PyObject *)self;
}

static PyObject *Caller_calls(Caller *self, void *closure) {
    return PyLong_FromUnsignedLongLong(self->calls);
}

static PyGetSetDef Caller_getset[] = {
    {"calls", (getter)Caller_calls, NULL, "direct calls made", NULL},
    {NULL},
};

static PyTypeObject CallerType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "workbench_fastcall.Caller",
    .tp_basicsize = sizeof(Caller),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_VECTORCALL | Py_TPFLAGS_HAVE_GC,
    .tp_new = Caller_new,
    .tp_dealloc = (destructor)Caller_dealloc,
    .tp_traverse = (traverseproc)Caller_traverse,
    .tp_clear = (inquiry)Caller_clear,
    .tp_free = PyObject_GC_Del,
    .tp_call = PyVectorcall_Call,
    .tp_vectorcall_offset = offsetof(Caller, vectorcall),
    .tp_getset = Caller_getset,
    .tp_doc = "A direct call into a CasADi-generated C function on bound arrays.",
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "workbench_fastcall", NULL, -1, NULL,
};

PyMODINIT_FUNC PyInit_workbench_fastcall(void) {
    if (PyType_Ready(&CallerType) < 0) return NULL;
    PyObject *m = PyModule_Create(&module);
    if (m == NULL) return NULL;
    Py_INCREF(&CallerType);
    if (PyModule_AddObject(m, "Caller", (PyObject *)&CallerType) < 0) {
        Py_DECREF(&CallerType);
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
