/* leolink._kernels: the compiled loops of the engine, the candidate tables and the
 * visibility search (C99; see src/leolink/engine/kernels.py for the Python side).
 *
 * Each loop repeats the floating point operations of the numpy code it replaces one for
 * one, in the same order, so that a value gets the same bits from either wherever
 * numpy's loops are the C library's: a sum of three products is (p0 + p2) + p1 (what
 * numpy.einsum does over a length-3 axis), the Dirichlet angle subtraction is
 * fma(c1, t1, c0 t0) (what the BLAS product of dirichlet_kernels does for up to 16
 * beams; see its docstring for more), the
 * transcendental functions are the C library's. Build flags (setup.py): no contraction
 * of a * b + c into an FMA (-ffp-contract=off) and no value-changing optimisation (no
 * -ffast-math); -fno-math-errno only lets sqrt be one instruction.
 *
 * Arrays come through the buffer protocol, with their strides (a column slice of a
 * (k, m) matrix is read in place); each is checked for its element type and number of
 * dimensions, its extents against the rows asked for and against each other (REQUIRE),
 * and the indices it holds against what they index (INDICES): a caller's mistake raises
 * ValueError instead of reading or writing outside a buffer. Every loop runs without the GIL over the rows
 * lo .. hi - 1 given to it, so that callers split large calls over threads
 * (leolink.compiled.run_rows); a row's values do not depend on the split.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* fma() is exact wherever it is computed: as the FMA instruction where the CPU has one (a
 * clone of the loop for it, chosen when the module loads), else by the C library. Nothing
 * else is contracted (-ffp-contract=off), so the clones give the same bits. */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__linux__) && \
    defined(__GLIBC__)
#define FMA_CLONES __attribute__((target_clones("fma", "default")))
/* The visibility loops' lanes: 8 doubles where the CPU has AVX-512, 4 with AVX2, 2
 * elsewhere; every lane does the same operations, so the width changes no bit. */
#define VECTOR_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define FMA_CLONES
#define VECTOR_CLONES
#endif

typedef struct {
    Py_buffer view;
    char *p;
    Py_ssize_t n[3];
    Py_ssize_t s[3];
    int held;
} Arr;

#define E1(a, T, i) (*(T *)((a).p + (Py_ssize_t)(i) * (a).s[0]))
#define E2(a, T, i, j) (*(T *)((a).p + (Py_ssize_t)(i) * (a).s[0] + (Py_ssize_t)(j) * (a).s[1]))
#define E3(a, T, i, j, k)                                                                 \
    (*(T *)((a).p + (Py_ssize_t)(i) * (a).s[0] + (Py_ssize_t)(j) * (a).s[1] +             \
            (Py_ssize_t)(k) * (a).s[2]))

/* The element type of a buffer: 'd' float64, 'f' float32, 'q' int64, 'b' int8, '?' bool;
 * 0 for anything else (another type, a non-native byte order). */
static int kind_of(const Py_buffer *v)
{
    const char *f = v->format ? v->format : "B";
    if (*f == '@' || *f == '=')
        f++;
    if (f[0] == '\0' || f[1] != '\0')
        return 0;
    switch (f[0]) {
    case 'd':
        return v->itemsize == 8 ? 'd' : 0;
    case 'f':
        return v->itemsize == 4 ? 'f' : 0;
    case 'q':
    case 'l':
        return v->itemsize == 8 ? 'q' : 0;
    case 'b':
        return v->itemsize == 1 ? 'b' : 0;
    case '?':
        return v->itemsize == 1 ? '?' : 0;
    }
    return 0;
}

static const char *type_name(int kind)
{
    switch (kind) {
    case 'd':
        return "float64";
    case 'f':
        return "float32";
    case 'q':
        return "int64";
    case 'b':
        return "int8";
    case '?':
        return "bool";
    }
    return "float64 or float32";
}

/* Take the buffer of ``o`` into ``a``: ``kind`` its element type ('F': float64 or float32),
 * ``nd`` its dimensions, ``writable`` whether the loop writes it. */
static int take(PyObject *o, Arr *a, int kind, int nd, int writable, const char *name)
{
    int flags = PyBUF_STRIDES | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(o, &a->view, flags) < 0)
        return -1;
    a->held = 1;
    int got = kind_of(&a->view);
    int ok = kind == 'F' ? (got == 'd' || got == 'f') : got == kind;
    if (!ok || a->view.ndim != nd) {
        PyErr_Format(PyExc_TypeError, "leolink._kernels: %s must be a %d-D %s array", name, nd,
                     type_name(kind));
        return -1;
    }
    a->p = (char *)a->view.buf;
    for (int i = 0; i < 3; i++) {
        a->n[i] = i < nd ? a->view.shape[i] : 1;
        a->s[i] = i < nd ? a->view.strides[i] : 0;
    }
    return 0;
}

static void release(Arr *a, int n)
{
    for (int i = 0; i < n; i++) {
        if (a[i].held) {
            PyBuffer_Release(&a[i].view);
            a[i].held = 0;
        }
    }
}

typedef struct {
    const char *name;
    int kind;
    int nd;
    int writable;
} Spec;

/* Take the buffers of ``objs`` as ``spec`` says; on failure every taken one is released. */
static int take_all(PyObject **objs, Arr *a, const Spec *spec, int n)
{
    for (int i = 0; i < n; i++) {
        a[i].held = 0;
    }
    for (int i = 0; i < n; i++) {
        if (take(objs[i], &a[i], spec[i].kind, spec[i].nd, spec[i].writable, spec[i].name) < 0) {
            release(a, n);
            return -1;
        }
    }
    return 0;
}

/* The arguments of kernel ``fn`` do not satisfy ``cond``: ValueError naming both. */
static PyObject *misfit(const char *fn, const char *cond)
{
    PyErr_Format(PyExc_ValueError, "leolink._kernels.%s: the arguments must satisfy %s", fn,
                 cond);
    return NULL;
}

/* Whether idx[lo .. hi - 1] all lie in 0 .. bound - 1; else ValueError naming the first
 * that does not. */
static int indices_in(const char *fn, const char *name, const Arr *idx, Py_ssize_t lo,
                      Py_ssize_t hi, Py_ssize_t bound)
{
    for (Py_ssize_t p = lo; p < hi; p++) {
        int64_t v = E1(*idx, int64_t, p);
        if (v < 0 || v >= bound) {
            PyErr_Format(PyExc_ValueError,
                         "leolink._kernels.%s: %s[%zd] = %lld is outside 0 .. %zd - 1", fn, name,
                         p, (long long)v, bound);
            return 0;
        }
    }
    return 1;
}

/* In a kernel whose buffers are ``Arr a[N]``, taken: on a failed check, release them and
 * raise. ROWS: lo .. hi - 1 a range of rows within n. */
#define N_ARR(a) ((int)(sizeof(a) / sizeof((a)[0])))
#define REQUIRE(cond)                                                                     \
    do {                                                                                  \
        if (!(cond)) {                                                                    \
            release(a, N_ARR(a));                                                         \
            return misfit(__func__, #cond);                                               \
        }                                                                                 \
    } while (0)
#define INDICES(idx, lo, hi, bound)                                                       \
    do {                                                                                  \
        if (!indices_in(__func__, #idx, &(idx), (lo), (hi), (bound))) {                   \
            release(a, N_ARR(a));                                                         \
            return NULL;                                                                  \
        }                                                                                 \
    } while (0)
#define ROWS(lo, hi, n) REQUIRE(0 <= (lo) && (lo) <= (hi) && (hi) <= (n))

static const double HALF_PI = 0.5 * M_PI;
static const double SCREEN_HALF_PI = 1.5707963267948966;
static const double DEG = 180.0 / M_PI; /* numpy.degrees multiplies by this constant */
static const double C4PI = 4.0 * M_PI;

/* numpy.einsum('k,k->', a, b) over three values: (a0 b0 + a2 b2) + a1 b1. */
static inline double dot3(double a0, double a1, double a2, double b0, double b1, double b2)
{
    return (a0 * b0 + a2 * b2) + a1 * b1;
}

/* leolink.antenna.array.ula_gain of one offset (numpy's operations, in order). */
static inline double ula_gain(double du, double n, double sin_tiny)
{
    double du_red = du - 2.0 * rint(0.5 * du);
    double x = HALF_PI * du_red;
    double s = sin(x);
    if (fabs(s) < sin_tiny)
        return n;
    double sn = sin(n * x);
    double g = (sn * sn) / (n * (s * s));
    if (g < 0.0) /* np.clip, which keeps NaN */
        return 0.0;
    return g > n ? n : g;
}

/* dirichlet_kernels of direction u into out[:, p] (coef: (2k, 4), the angle-subtraction
 * coefficients of dirichlet_kernels). */
static inline void dirichlet_of(double u, double s, double c, double sn, double cn,
                                const Arr *beam_u, const Arr *coef, double n, Arr *out,
                                Py_ssize_t p, double sin_recompute, double sin_tiny)
{
    Py_ssize_t k = beam_u->n[0];
    double inv_n = 1.0 / n;
    for (Py_ssize_t j = 0; j < k; j++) {
        double den = fma(E2(*coef, double, j, 1), c, E2(*coef, double, j, 0) * s);
        if (fabs(den) < sin_recompute) {
            E2(*out, double, j, p) = ula_gain(u - E1(*beam_u, double, j), n, sin_tiny);
            continue;
        }
        double g = fma(E2(*coef, double, k + j, 3), cn, E2(*coef, double, k + j, 2) * sn) / den;
        g = (g * g) * inv_n;
        E2(*out, double, j, p) = g > n ? n : g; /* np.minimum, which keeps NaN */
    }
}

/* dirichlet_of, the sines and cosines of dirichlet_trig computed here. */
static inline void dirichlet(double u, const Arr *beam_u, const Arr *coef, double n, Arr *out,
                             Py_ssize_t p, double sin_recompute, double sin_tiny)
{
    double x = HALF_PI * u;
    double s = sin(x), c = cos(x);
    double xn = x * n;
    double sn = sin(xn), cn = cos(xn);
    dirichlet_of(u, s, c, sn, cn, beam_u, coef, n, out, p, sin_recompute, sin_tiny);
}

/* The directions lo .. hi - 1 of dirichlet_kernels (a[]: u, trig, beam_u, coef, out). */
FMA_CLONES static void dirichlet_rows(const Arr *a, double n, double sin_recompute,
                                      double sin_tiny, Py_ssize_t lo, Py_ssize_t hi)
{
    Arr u = a[0], trig = a[1], beam_u = a[2], coef = a[3], out = a[4];
    for (Py_ssize_t p = lo; p < hi; p++) {
        dirichlet_of(E1(u, double, p), E2(trig, double, 0, p), E2(trig, double, 1, p),
                     E2(trig, double, 2, p), E2(trig, double, 3, p), &beam_u, &coef, n, &out,
                     p, sin_recompute, sin_tiny);
    }
}

/* dirichlet_kernels(u, trig, beam_u, coef, n, sin_recompute, sin_tiny, out):
 * leolink.antenna.array.dirichlet_kernels of the directions u (m,) against the beams
 * beam_u (k,), given their dirichlet_trig (4, m) and dirichlet_coefficients (2k, 4), into
 * out (k, m): fma(c1, t1, c0 t0) as its BLAS product, the same recomputation near a peak. */
static PyObject *dirichlet_kernels(PyObject *self, PyObject *args)
{
    PyObject *o[5];
    double n, sin_recompute, sin_tiny;
    if (!PyArg_ParseTuple(args, "OOOOdddO", &o[0], &o[1], &o[2], &o[3], &n, &sin_recompute,
                          &sin_tiny, &o[4]))
        return NULL;
    static const Spec spec[5] = {{"u", 'd', 1, 0},    {"trig", 'd', 2, 0}, {"beam_u", 'd', 1, 0},
                                 {"coef", 'd', 2, 0}, {"out", 'd', 2, 1}};
    Arr a[5];
    if (take_all(o, a, spec, 5) < 0)
        return NULL;
    Arr u = a[0], trig = a[1], beam_u = a[2], coef = a[3], out = a[4];
    REQUIRE(trig.n[0] >= 4 && trig.n[1] == u.n[0]);
    REQUIRE(coef.n[0] == 2 * beam_u.n[0] && coef.n[1] >= 4);
    REQUIRE(out.n[0] == beam_u.n[0] && out.n[1] == u.n[0]);
    Py_BEGIN_ALLOW_THREADS;
    dirichlet_rows(a, n, sin_recompute, sin_tiny, 0, a[0].n[0]);
    Py_END_ALLOW_THREADS;
    release(a, 5);
    Py_RETURN_NONE;
}

/* links_kernel(ut_pos, ut_up, sphere, r_ut, sat_pos, ax_x, ax_y, ut, sat, min_el, bx, cx,
 *              nx, by, cy, ny, rel, rho2, rho, elevation, visible, kx, ky, lo, hi,
 *              sin_recompute, sin_tiny) */
/* The rows lo .. hi - 1 of links_kernel (a[] its 19 arrays, in its order). */
FMA_CLONES static void links_rows(const Arr *a, int sphere, double min_el, double nx, double ny,
                                  double sin_recompute, double sin_tiny, Py_ssize_t lo,
                                  Py_ssize_t hi)
{
    Arr ut_pos = a[0], ut_up = a[1], r_ut = a[2], sat_pos = a[3], ax_x = a[4], ax_y = a[5];
    Arr ut = a[6], sat = a[7], bx = a[8], cx = a[9], by = a[10], cy = a[11];
    Arr rel = a[12], rho2 = a[13], rho = a[14], elevation = a[15], visible = a[16];
    Arr kx = a[17], ky = a[18];
    for (Py_ssize_t p = lo; p < hi; p++) {
        int64_t i = E1(ut, int64_t, p), j = E1(sat, int64_t, p);
        double r0 = E2(ut_pos, double, i, 0) - E2(sat_pos, double, j, 0);
        double r1 = E2(ut_pos, double, i, 1) - E2(sat_pos, double, j, 1);
        double r2 = E2(ut_pos, double, i, 2) - E2(sat_pos, double, j, 2);
        E2(rel, double, p, 0) = r0;
        E2(rel, double, p, 1) = r1;
        E2(rel, double, p, 2) = r2;
        double d2 = dot3(r0, r1, r2, r0, r1, r2);
        double d = sqrt(d2);
        E1(rho2, double, p) = d2;
        E1(rho, double, p) = d;
        double s_el;
        if (sphere) {
            s_el = -dot3(r0, r1, r2, E2(ut_pos, double, i, 0), E2(ut_pos, double, i, 1),
                         E2(ut_pos, double, i, 2)) /
                   (d * E1(r_ut, double, i));
        } else {
            s_el = -dot3(r0, r1, r2, E2(ut_up, double, i, 0), E2(ut_up, double, i, 1),
                         E2(ut_up, double, i, 2)) /
                   d;
        }
        if (s_el < -1.0) /* np.clip, which keeps NaN */
            s_el = -1.0;
        else if (s_el > 1.0)
            s_el = 1.0;
        double el = asin(s_el);
        E1(elevation, double, p) = el;
        E1(visible, char, p) = el >= min_el;
        double inv = 1.0 / d;
        double ux = dot3(r0, r1, r2, E2(ax_x, double, j, 0), E2(ax_x, double, j, 1),
                         E2(ax_x, double, j, 2)) *
                    inv;
        double uy = dot3(r0, r1, r2, E2(ax_y, double, j, 0), E2(ax_y, double, j, 1),
                         E2(ax_y, double, j, 2)) *
                    inv;
        dirichlet(ux, &bx, &cx, nx, &kx, p, sin_recompute, sin_tiny);
        dirichlet(uy, &by, &cy, ny, &ky, p, sin_recompute, sin_tiny);
    }
}

static PyObject *links_kernel(PyObject *self, PyObject *args)
{
    PyObject *o[20];
    int sphere;
    double min_el, nx, ny, sin_recompute, sin_tiny;
    Py_ssize_t lo, hi;
    if (!PyArg_ParseTuple(args, "OOpOOOOOOdOOdOOdOOOOOOOnndd", &o[0], &o[1], &sphere, &o[2],
                          &o[3], &o[4], &o[5], &o[6], &o[7], &min_el, &o[8], &o[9], &nx, &o[10],
                          &o[11], &ny, &o[12], &o[13], &o[14], &o[15], &o[16], &o[17], &o[18],
                          &lo, &hi, &sin_recompute, &sin_tiny))
        return NULL;
    static const Spec spec[19] = {
        {"ut_pos", 'd', 2, 0}, {"ut_up", 'd', 2, 0},    {"r_ut", 'd', 1, 0},
        {"sat_pos", 'd', 2, 0}, {"ax_x", 'd', 2, 0},    {"ax_y", 'd', 2, 0},
        {"ut", 'q', 1, 0},      {"sat", 'q', 1, 0},     {"bx", 'd', 1, 0},
        {"cx", 'd', 2, 0},      {"by", 'd', 1, 0},      {"cy", 'd', 2, 0},
        {"rel", 'd', 2, 1},     {"rho2", 'd', 1, 1},    {"rho", 'd', 1, 1},
        {"elevation", 'd', 1, 1}, {"visible", '?', 1, 1}, {"kx", 'd', 2, 1},
        {"ky", 'd', 2, 1}};
    Arr a[19];
    if (take_all(o, a, spec, 19) < 0)
        return NULL;
    Arr ut_pos = a[0], ut_up = a[1], r_ut = a[2], sat_pos = a[3], ax_x = a[4], ax_y = a[5];
    Arr ut = a[6], sat = a[7], bx = a[8], cx = a[9], by = a[10], cy = a[11];
    Arr rel = a[12], rho2 = a[13], rho = a[14], elevation = a[15], visible = a[16];
    Arr kx = a[17], ky = a[18];
    Py_ssize_t n_ut = ut_pos.n[0], n_sat = sat_pos.n[0];
    ROWS(lo, hi, ut.n[0]);
    REQUIRE(sat.n[0] >= hi && rel.n[0] >= hi && rho2.n[0] >= hi && rho.n[0] >= hi);
    REQUIRE(elevation.n[0] >= hi && visible.n[0] >= hi && kx.n[1] >= hi && ky.n[1] >= hi);
    REQUIRE(ut_pos.n[1] >= 3 && sat_pos.n[1] >= 3 && rel.n[1] >= 3);
    REQUIRE(ax_x.n[0] >= n_sat && ax_x.n[1] >= 3 && ax_y.n[0] >= n_sat && ax_y.n[1] >= 3);
    REQUIRE(sphere ? r_ut.n[0] >= n_ut : ut_up.n[0] >= n_ut && ut_up.n[1] >= 3);
    REQUIRE(cx.n[0] == 2 * bx.n[0] && cx.n[1] >= 4 && kx.n[0] == bx.n[0]);
    REQUIRE(cy.n[0] == 2 * by.n[0] && cy.n[1] >= 4 && ky.n[0] == by.n[0]);
    INDICES(ut, lo, hi, n_ut);
    INDICES(sat, lo, hi, n_sat);
    Py_BEGIN_ALLOW_THREADS;
    links_rows(a, sphere, min_el, nx, ny, sin_recompute, sin_tiny, lo, hi);
    Py_END_ALLOW_THREADS;
    release(a, 19);
    Py_RETURN_NONE;
}

/* snr_kernel(kx, ky, path_snr, ix, iy, out, lo, hi): Links.snr_db_bm,
 * (10 log10 k_x + 10 log10 k_y) + 10 log10 p, (n_beam, m), of the pairs lo .. hi - 1. */
static PyObject *snr_kernel(PyObject *self, PyObject *args)
{
    PyObject *o[6];
    Py_ssize_t lo, hi;
    if (!PyArg_ParseTuple(args, "OOOOOOnn", &o[0], &o[1], &o[2], &o[3], &o[4], &o[5], &lo, &hi))
        return NULL;
    static const Spec spec[6] = {{"kx", 'd', 2, 0}, {"ky", 'd', 2, 0}, {"path_snr", 'd', 1, 0},
                                 {"ix", 'q', 1, 0}, {"iy", 'q', 1, 0}, {"out", 'd', 2, 1}};
    Arr a[6];
    if (take_all(o, a, spec, 6) < 0)
        return NULL;
    Arr kx = a[0], ky = a[1], path = a[2], ix = a[3], iy = a[4], out = a[5];
    Py_ssize_t nkx = kx.n[0], nky = ky.n[0], nb = ix.n[0];
    ROWS(lo, hi, path.n[0]);
    REQUIRE(kx.n[1] >= hi && ky.n[1] >= hi && out.n[1] >= hi);
    REQUIRE(iy.n[0] == nb && out.n[0] == nb);
    INDICES(ix, 0, nb, nkx);
    INDICES(iy, 0, nb, nky);
    double *lx = malloc(sizeof(double) * (size_t)(nkx + nky + 1));
    if (lx == NULL) {
        release(a, 6);
        return PyErr_NoMemory();
    }
    double *ly = lx + nkx;
    Py_BEGIN_ALLOW_THREADS;
    for (Py_ssize_t p = lo; p < hi; p++) {
        for (Py_ssize_t q = 0; q < nkx; q++)
            lx[q] = 10.0 * log10(E2(kx, double, q, p));
        for (Py_ssize_t q = 0; q < nky; q++)
            ly[q] = 10.0 * log10(E2(ky, double, q, p));
        double pdb = 10.0 * log10(E1(path, double, p));
        for (Py_ssize_t b = 0; b < nb; b++)
            E2(out, double, b, p) = (lx[E1(ix, int64_t, b)] + ly[E1(iy, int64_t, b)]) + pdb;
    }
    Py_END_ALLOW_THREADS;
    free(lx);
    release(a, 6);
    Py_RETURN_NONE;
}

/* best_beam_kernel's margin and ranges (see leolink/engine/kernels.py). */
static const double TIE_MARGIN = 1e-9;
static const double BB_PATH_MIN = 1e-150, BB_PATH_MAX = 1e150;
static const double BB_SNR_MIN = 1e-100, BB_SNR_MAX = 1e100;

/* numpy.argmax of every beam's dB value (the first NaN, else the first maximum). */
static inline void best_of_all(const Arr *kx, const Arr *ky, double path, const Arr *ix,
                               const Arr *iy, Arr *best, Arr *best_db, Py_ssize_t p)
{
    double pdb = 10.0 * log10(path);
    int64_t i = 0;
    double d_best = 0.0;
    for (Py_ssize_t b = 0; b < ix->n[0]; b++) {
        double d = (10.0 * log10(E2(*kx, double, E1(*ix, int64_t, b), p)) +
                    10.0 * log10(E2(*ky, double, E1(*iy, int64_t, b), p))) +
                   pdb;
        if (d != d) {
            i = b;
            d_best = d;
            break;
        }
        if (b == 0 || d > d_best) {
            i = b;
            d_best = d;
        }
    }
    E1(*best, int64_t, p) = i;
    E1(*best_db, double, p) = d_best;
}

/* best_beam_kernel(kx, ky, path_snr, ix, iy, with_db, best, best_db, lo, hi):
 * numpy.argmax(Links.snr_db_bm(ix, iy), axis=0) and that beam's dB value, without the
 * (n_beam, m) matrix (leolink/engine/kernels.py). */
static PyObject *best_beam_kernel(PyObject *self, PyObject *args)
{
    PyObject *o[7];
    int with_db;
    Py_ssize_t lo, hi;
    if (!PyArg_ParseTuple(args, "OOOOOpOOnn", &o[0], &o[1], &o[2], &o[3], &o[4], &with_db, &o[5],
                          &o[6], &lo, &hi))
        return NULL;
    static const Spec spec[7] = {{"kx", 'd', 2, 0},   {"ky", 'd', 2, 0},     {"path_snr", 'd', 1, 0},
                                 {"ix", 'q', 1, 0},   {"iy", 'q', 1, 0},     {"best", 'q', 1, 1},
                                 {"best_db", 'd', 1, 1}};
    Arr a[7];
    if (take_all(o, a, spec, 7) < 0)
        return NULL;
    Arr kx = a[0], ky = a[1], path_snr = a[2], ix = a[3], iy = a[4], best = a[5], best_db = a[6];
    Py_ssize_t nb = ix.n[0];
    ROWS(lo, hi, path_snr.n[0]);
    REQUIRE(kx.n[1] >= hi && ky.n[1] >= hi && best.n[0] >= hi && best_db.n[0] >= hi);
    REQUIRE(iy.n[0] == nb);
    INDICES(ix, 0, nb, kx.n[0]);
    INDICES(iy, 0, nb, ky.n[0]);
    Py_BEGIN_ALLOW_THREADS;
    for (Py_ssize_t p = lo; p < hi; p++) {
        double path = E1(path_snr, double, p);
        if (path != path) {
            E1(best, int64_t, p) = 0;
            E1(best_db, double, p) = NAN;
            continue;
        }
        double s_max = -1.0, s_2nd = -1.0;
        int64_t i = 0;
        int nan = 0;
        for (Py_ssize_t b = 0; b < nb; b++) {
            double s = (E2(kx, double, E1(ix, int64_t, b), p) *
                        E2(ky, double, E1(iy, int64_t, b), p)) *
                       path;
            nan |= s != s;
            int up = s > s_max;
            double other = up ? s_max : s;
            s_2nd = other > s_2nd ? other : s_2nd; /* (a NaN sets nan: never read) */
            i = up ? b : i;
            s_max = up ? s : s_max;
        }
        int clear = s_2nd < s_max * (1.0 - TIE_MARGIN) && !nan;
        if (clear && BB_PATH_MIN <= path && path <= BB_PATH_MAX && BB_SNR_MIN <= s_max &&
            s_max <= BB_SNR_MAX) {
            E1(best, int64_t, p) = i;
            if (with_db) {
                E1(best_db, double, p) = (10.0 * log10(E2(kx, double, E1(ix, int64_t, i), p)) +
                                          10.0 * log10(E2(ky, double, E1(iy, int64_t, i), p))) +
                                         10.0 * log10(path);
            }
        } else {
            best_of_all(&kx, &ky, path, &ix, &iy, &best, &best_db, p);
        }
    }
    Py_END_ALLOW_THREADS;
    release(a, 7);
    Py_RETURN_NONE;
}

/* numpy.mod(x, 360.0) (fmod, then the divisor's sign). */
static inline double mod360(double x)
{
    double m = fmod(x, 360.0);
    if (m != 0.0) {
        if (m < 0.0)
            m += 360.0;
    } else {
        m = 0.0;
    }
    return m;
}

/* serve_kernel(kx, ky, path_snr, rel, slant, elevation, pair, beam, served, ix, iy, fading,
 *              i_other, ut_vel, ut_acc, sat_vel, sat_acc, ut_pos, enu, has_enu, k_dop,
 *              freq, bw, rx, atm, out, lo, hi): LinkEngine.serve_pairs for a full beam
 * lattice with one colour, per row; out (16, n) in the order of
 * SERVE_COLUMNS + SERVE_GEOMETRY_COLUMNS. */
static PyObject *serve_kernel(PyObject *self, PyObject *args)
{
    PyObject *o[22];
    int has_enu;
    double k_dop, freq, bw;
    Py_ssize_t lo, hi;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOOOOOOOOOOOpdddOOOnn", &o[0], &o[1], &o[2], &o[3],
                          &o[4], &o[5], &o[6], &o[7], &o[8], &o[9], &o[10], &o[11], &o[12], &o[13],
                          &o[14], &o[15], &o[16], &o[17], &o[18], &has_enu, &k_dop, &freq, &bw,
                          &o[19], &o[20], &o[21], &lo, &hi))
        return NULL;
    static const Spec spec[22] = {
        {"kx", 'd', 2, 0},      {"ky", 'd', 2, 0},      {"path_snr", 'd', 1, 0},
        {"rel", 'd', 2, 0},     {"slant", 'd', 1, 0},   {"elevation", 'd', 1, 0},
        {"pair", 'q', 1, 0},    {"beam", 'q', 1, 0},    {"served", '?', 1, 0},
        {"ix", 'q', 1, 0},      {"iy", 'q', 1, 0},      {"fading", 'd', 1, 0},
        {"i_other", 'd', 1, 0}, {"ut_vel", 'd', 2, 0},  {"ut_acc", 'd', 2, 0},
        {"sat_vel", 'd', 2, 0}, {"sat_acc", 'd', 2, 0}, {"ut_pos", 'd', 2, 0},
        {"enu", 'd', 3, 0},     {"rx", 'd', 1, 0},      {"atm", 'd', 1, 0},
        {"out", 'd', 2, 1}};
    Arr a[22];
    if (take_all(o, a, spec, 22) < 0)
        return NULL;
    Arr kx = a[0], ky = a[1], path_snr = a[2], rel = a[3], slant = a[4], elevation = a[5];
    Arr pair = a[6], beam = a[7], served = a[8], ix = a[9], iy = a[10], fading = a[11];
    Arr i_other = a[12], ut_vel = a[13], ut_acc = a[14], sat_vel = a[15], sat_acc = a[16];
    Arr ut_pos = a[17], enu = a[18], rx = a[19], atm = a[20], out = a[21];
    Py_ssize_t n_pair = path_snr.n[0], n_beam = ix.n[0];
    ROWS(lo, hi, pair.n[0]);
    REQUIRE(beam.n[0] >= hi && served.n[0] >= hi && fading.n[0] >= hi && i_other.n[0] >= hi);
    REQUIRE(rx.n[0] >= hi && atm.n[0] >= hi && out.n[0] >= 16 && out.n[1] >= hi);
    REQUIRE(ut_vel.n[0] >= hi && ut_acc.n[0] >= hi && sat_vel.n[0] >= hi && sat_acc.n[0] >= hi);
    REQUIRE(ut_vel.n[1] >= 3 && ut_acc.n[1] >= 3 && sat_vel.n[1] >= 3 && sat_acc.n[1] >= 3);
    REQUIRE(has_enu ? enu.n[0] >= hi && enu.n[1] >= 2 && enu.n[2] >= 3
                    : ut_pos.n[0] >= hi && ut_pos.n[1] >= 3);
    REQUIRE(kx.n[0] >= 1 && ky.n[0] >= 1 && kx.n[1] >= n_pair && ky.n[1] >= n_pair);
    REQUIRE(rel.n[0] >= n_pair && rel.n[1] >= 3 && slant.n[0] >= n_pair &&
            elevation.n[0] >= n_pair);
    REQUIRE(iy.n[0] == n_beam);
    INDICES(pair, lo, hi, n_pair);
    INDICES(beam, lo, hi, n_beam);
    INDICES(ix, 0, n_beam, kx.n[0]);
    INDICES(iy, 0, n_beam, ky.n[0]);
    Py_BEGIN_ALLOW_THREADS;
    const double c = 299792458.0;
    const double ln2 = log(2.0);
    for (Py_ssize_t r = lo; r < hi; r++) {
        int64_t p = E1(pair, int64_t, r), b = E1(beam, int64_t, r);
        double nan = E1(served, char, r) ? 1.0 : NAN;
        double sx = E2(kx, double, 0, p), sy = E2(ky, double, 0, p);
        for (Py_ssize_t q = 1; q < kx.n[0]; q++)
            sx += E2(kx, double, q, p);
        for (Py_ssize_t q = 1; q < ky.n[0]; q++)
            sy += E2(ky, double, q, p);
        double g_sig = E2(kx, double, E1(ix, int64_t, b), p) * E2(ky, double, E1(iy, int64_t, b), p);
        double g_int = sx * sy - g_sig;
        double path = E1(path_snr, double, p) * E1(fading, double, r);
        double snr = g_sig * path;
        double sinr = snr / ((g_int * path + E1(i_other, double, r)) + 1.0);
        double se = log1p(sinr) / ln2;
        double l0 = -E2(rel, double, p, 0), l1 = -E2(rel, double, p, 1), l2 = -E2(rel, double, p, 2);
        double rho_k = sqrt(dot3(l0, l1, l2, l0, l1, l2));
        double sv0 = E2(sat_vel, double, r, 0), sv1 = E2(sat_vel, double, r, 1);
        double sv2 = E2(sat_vel, double, r, 2);
        double uv0 = E2(ut_vel, double, r, 0), uv1 = E2(ut_vel, double, r, 1);
        double uv2 = E2(ut_vel, double, r, 2);
        double v_sat = dot3(sv0, sv1, sv2, l0, l1, l2) / rho_k;
        double v_ut = dot3(uv0, uv1, uv2, l0, l1, l2) / rho_k;
        double v0 = sv0 - uv0, v1 = sv1 - uv1, v2_ = sv2 - uv2;
        double v2 = dot3(v0, v1, v2_, v0, v1, v2_);
        double a0 = E2(sat_acc, double, r, 0) - E2(ut_acc, double, r, 0);
        double a1 = E2(sat_acc, double, r, 1) - E2(ut_acc, double, r, 1);
        double a2 = E2(sat_acc, double, r, 2) - E2(ut_acc, double, r, 2);
        double rho_dot = v_sat - v_ut;
        double rho_ddot = ((v2 + dot3(l0, l1, l2, a0, a1, a2)) - rho_dot * rho_dot) / rho_k;
        double perp = v2 - rho_dot * rho_dot;
        if (perp < 0.0) /* np.maximum(., 0), which keeps NaN */
            perp = 0.0;
        double ang = sqrt(perp) / rho_k;
        double east, north;
        if (has_enu) {
            east = dot3(l0, l1, l2, E3(enu, double, r, 0, 0), E3(enu, double, r, 0, 1),
                        E3(enu, double, r, 0, 2));
            north = dot3(l0, l1, l2, E3(enu, double, r, 1, 0), E3(enu, double, r, 1, 1),
                         E3(enu, double, r, 1, 2));
        } else { /* links.azimuth_deg: the sphere's east and north times h r */
            double x = E2(ut_pos, double, r, 0), y = E2(ut_pos, double, r, 1);
            double z = E2(ut_pos, double, r, 2);
            double h2 = x * x + y * y;
            east = sqrt(h2 + z * z) * (x * l1 - y * l0);
            north = h2 * l2 - z * (x * l0 + y * l1);
        }
        double rho = E1(slant, double, p);
        E2(out, double, 0, r) = (E1(elevation, double, p) * DEG) * nan;
        E2(out, double, 1, r) = rho * nan;
        E2(out, double, 2, r) = (10.0 * log10(g_sig)) * nan;
        E2(out, double, 3, r) = E1(rx, double, r) * nan;
        E2(out, double, 4, r) = (20.0 * log10(((C4PI * rho) * freq) / c)) * nan;
        E2(out, double, 5, r) = E1(atm, double, r) * nan;
        E2(out, double, 6, r) = (10.0 * log10(snr)) * nan;
        E2(out, double, 7, r) = (10.0 * log10(sinr)) * nan;
        E2(out, double, 8, r) = se * nan;
        E2(out, double, 9, r) = se * (bw * nan);
        E2(out, double, 10, r) = (-k_dop * rho_dot) * nan;
        E2(out, double, 11, r) = (-k_dop * v_sat) * nan;
        E2(out, double, 12, r) = (k_dop * v_ut) * nan;
        E2(out, double, 13, r) = (-k_dop * rho_ddot) * nan;
        E2(out, double, 14, r) = (ang * DEG) * nan;
        E2(out, double, 15, r) = mod360(atan2(east, north) * DEG) * nan;
    }
    Py_END_ALLOW_THREADS;
    release(a, 22);
    Py_RETURN_NONE;
}

/* min(n, 1 / (n s^2)), s a lower bound of sin(pi d / 2) and d the distance from u to the
 * nearest beam cosine modulo 2 (screening.envelope). */
static inline double screen_envelope(double u, const Arr *beams, double n)
{
    Py_ssize_t k = beams->n[0];
    double first = E1(*beams, double, 0), last = E1(*beams, double, k - 1);
    double d = 2.0 - (u - first > last - u ? u - first : last - u);
    for (Py_ssize_t q = 0; q < k; q++) {
        double e = fabs(u - E1(*beams, double, q));
        d = e < d ? e : d;
    }
    double dc = d > 0.0 ? d : 0.0;
    double x = SCREEN_HALF_PI * (dc < 1.0 ? dc : 1.0);
    double x2 = x * x;
    double s = x * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0)));
    if (s <= 0.0)
        return n;
    double v = 1.0 / (n * s * s);
    return n < v ? n : v;
}

/* One pair of screening.screen: UT at p with up e (unit), satellite j; k = K (1 + slack)
 * times the UT's factor. */
static inline void screen_pair(double px, double py, double pz, double ex, double ey, double ez,
                               double k, const Arr *sat_pos, const Arr *ax_x, const Arr *ax_y,
                               Py_ssize_t j, const Arr *bx, const Arr *by, double nx, double ny,
                               double s_lo, double s_hi, int8_t *code, double *bound,
                               double *sin_out)
{
    double dx = px - E2(*sat_pos, double, j, 0), dy = py - E2(*sat_pos, double, j, 1);
    double dz = pz - E2(*sat_pos, double, j, 2);
    double rho2 = dx * dx + dy * dy + dz * dz;
    double inv = 1.0 / sqrt(rho2);
    double s_el = -(dx * ex + dy * ey + dz * ez) * inv;
    *sin_out = s_el;
    if (s_el < s_lo) {
        *code = 0;
        *bound = -1.0;
        return;
    }
    *code = s_el >= s_hi ? 2 : 1;
    double ux = (dx * E2(*ax_x, double, j, 0) + dy * E2(*ax_x, double, j, 1) +
                 dz * E2(*ax_x, double, j, 2)) *
                inv;
    double uy = (dx * E2(*ax_y, double, j, 0) + dy * E2(*ax_y, double, j, 1) +
                 dz * E2(*ax_y, double, j, 2)) *
                inv;
    *bound = k / rho2 * screen_envelope(ux, bx, nx) * screen_envelope(uy, by, ny);
}

/* The unit up of UT i: its radius's direction on the sphere, else ut_up's row. */
static inline void screen_up(const Arr *ut_pos, const Arr *ut_up, int sphere, Py_ssize_t i,
                             double *ex, double *ey, double *ez)
{
    if (sphere) {
        double px = E2(*ut_pos, double, i, 0), py = E2(*ut_pos, double, i, 1);
        double pz = E2(*ut_pos, double, i, 2);
        double r = sqrt(px * px + py * py + pz * pz);
        *ex = px / r;
        *ey = py / r;
        *ez = pz / r;
    } else {
        *ex = E2(*ut_up, double, i, 0);
        *ey = E2(*ut_up, double, i, 1);
        *ez = E2(*ut_up, double, i, 2);
    }
}

/* screen_ragged(ut_pos, ut_up, sphere, sat_pos, ax_x, ax_y, bx, by, nx, ny, k_lin, s_min, band,
 *               slack, ut_factor, cap_start, group, start, code, bound, sin_out, lo, hi):
 * screening.screen's codes, bounds and sin(elevation) of UT i with the satellites of its
 * group g = group[i], the rows cap_start[g] .. cap_start[g + 1] - 1 of sat_pos, ax_x and
 * ax_y, written in that order at start[i] .. start[i + 1] - 1 of the flat code, bound and
 * sin_out, for the UTs lo .. hi - 1 (screening.screen_ragged; screening.screen: one group
 * of every satellite). It rounds differently from the numpy code; both bounds hold (it
 * decides what is evaluated, never a value that reaches an output). */
static PyObject *screen_ragged(PyObject *self, PyObject *args)
{
    PyObject *o[14];
    int sphere;
    double nx, ny, k_lin, s_min, band, slack;
    Py_ssize_t lo, hi;
    if (!PyArg_ParseTuple(args, "OOpOOOOOddddddOOOOOOOnn", &o[0], &o[1], &sphere, &o[2], &o[3],
                          &o[4], &o[5], &o[6], &nx, &ny, &k_lin, &s_min, &band, &slack, &o[7],
                          &o[8], &o[9], &o[10], &o[11], &o[12], &o[13], &lo, &hi))
        return NULL;
    static const Spec spec[14] = {
        {"ut_pos", 'd', 2, 0},    {"ut_up", 'd', 2, 0},     {"sat_pos", 'd', 2, 0},
        {"ax_x", 'd', 2, 0},      {"ax_y", 'd', 2, 0},      {"bx", 'd', 1, 0},
        {"by", 'd', 1, 0},        {"ut_factor", 'd', 1, 0}, {"cap_start", 'q', 1, 0},
        {"group", 'q', 1, 0},     {"start", 'q', 1, 0},     {"code", 'b', 1, 1},
        {"bound", 'd', 1, 1},     {"sin_out", 'd', 1, 1}};
    Arr a[14];
    if (take_all(o, a, spec, 14) < 0)
        return NULL;
    Arr ut_pos = a[0], ut_up = a[1], sat_pos = a[2], ax_x = a[3], ax_y = a[4], bx = a[5];
    Arr by = a[6], ut_factor = a[7], cap_start = a[8], group = a[9], start = a[10];
    Arr code = a[11], bound = a[12], sin_out = a[13];
    Py_ssize_t n_s = sat_pos.n[0], m = code.n[0], n_g = cap_start.n[0] - 1;
    ROWS(lo, hi, start.n[0] - 1);
    REQUIRE(n_g >= 0 && group.n[0] >= hi);
    REQUIRE(ut_pos.n[0] >= hi && ut_pos.n[1] >= 3 && ut_factor.n[0] >= hi);
    REQUIRE(sphere || (ut_up.n[0] >= hi && ut_up.n[1] >= 3));
    REQUIRE(bound.n[0] >= m && sin_out.n[0] >= m);
    REQUIRE(ax_x.n[0] >= n_s && ax_y.n[0] >= n_s);
    REQUIRE(sat_pos.n[1] >= 3 && ax_x.n[1] >= 3 && ax_y.n[1] >= 3);
    REQUIRE(bx.n[0] >= 1 && by.n[0] >= 1);
    INDICES(cap_start, 0, n_g + 1, n_s + 1);
    INDICES(group, lo, hi, n_g);
    INDICES(start, lo, hi + 1, m + 1);
    for (Py_ssize_t i = lo; i < hi; i++) {
        int64_t g = E1(group, int64_t, i);
        int64_t n_cap = E1(cap_start, int64_t, g + 1) - E1(cap_start, int64_t, g);
        REQUIRE(n_cap >= 0 && E1(start, int64_t, i + 1) - E1(start, int64_t, i) == n_cap);
    }
    Py_BEGIN_ALLOW_THREADS;
    double s_lo = s_min - band, s_hi = s_min + band;
    for (Py_ssize_t i = lo; i < hi; i++) {
        double px = E2(ut_pos, double, i, 0), py = E2(ut_pos, double, i, 1);
        double pz = E2(ut_pos, double, i, 2);
        double ex, ey, ez;
        screen_up(&ut_pos, &ut_up, sphere, i, &ex, &ey, &ez);
        double k = k_lin * (1.0 + slack) * E1(ut_factor, double, i);
        int64_t c0 = E1(cap_start, int64_t, E1(group, int64_t, i)), q0 = E1(start, int64_t, i);
        for (int64_t q = q0; q < E1(start, int64_t, i + 1); q++)
            screen_pair(px, py, pz, ex, ey, ez, k, &sat_pos, &ax_x, &ax_y, c0 + q - q0, &bx, &by,
                        nx, ny, s_lo, s_hi, &E1(code, int8_t, q), &E1(bound, double, q),
                        &E1(sin_out, double, q));
    }
    Py_END_ALLOW_THREADS;
    release(a, 14);
    Py_RETURN_NONE;
}

/* ---- the candidate tables (leolink.sim.candidates.table): integer comparisons and maxima,
 * nothing rounded ---- */

/* table_best(cell, snr_db, out_cell, out_db): Candidates.best, each row's highest SNR
 * ignoring NaN, ties to the lowest cell id; -1 and NaN where none exceeds -inf. (A tie of
 * -0.0 and +0.0 gives the first zero; no SNR of the simulator is a signed zero.) */
static PyObject *table_best(PyObject *self, PyObject *args)
{
    PyObject *o[4];
    if (!PyArg_ParseTuple(args, "OOOO", &o[0], &o[1], &o[2], &o[3]))
        return NULL;
    static const Spec spec[4] = {{"cell", 'q', 2, 0}, {"snr_db", 'd', 2, 0},
                                 {"out_cell", 'q', 1, 1}, {"out_db", 'd', 1, 1}};
    Arr a[4];
    if (take_all(o, a, spec, 4) < 0)
        return NULL;
    Arr cell = a[0], snr = a[1], out_cell = a[2], out_db = a[3];
    REQUIRE(snr.n[0] == cell.n[0] && snr.n[1] == cell.n[1]);
    REQUIRE(out_cell.n[0] >= cell.n[0] && out_db.n[0] >= cell.n[0]);
    Py_BEGIN_ALLOW_THREADS;
    for (Py_ssize_t i = 0; i < cell.n[0]; i++) {
        double top_db = -INFINITY;
        int64_t top_cell = INT64_MAX;
        for (Py_ssize_t j = 0; j < cell.n[1]; j++) {
            double v = E2(snr, double, i, j);
            int64_t c = E2(cell, int64_t, i, j);
            if (v > top_db) { /* (false for NaN) */
                top_db = v;
                top_cell = c;
            } else if (v == top_db && v > -INFINITY && c < top_cell) {
                top_cell = c;
            }
        }
        if (top_db > -INFINITY) {
            E1(out_cell, int64_t, i) = top_cell;
            E1(out_db, double, i) = top_db;
        } else {
            E1(out_cell, int64_t, i) = -1;
            E1(out_db, double, i) = NAN;
        }
    }
    Py_END_ALLOW_THREADS;
    release(a, 4);
    Py_RETURN_NONE;
}

/* table_slots(cell, wanted, out): Candidates.slot_of, out (n_query, n_ut) the first slot of
 * row i holding wanted[q, i], -1 where none does or wanted[q, i] < 0. */
static PyObject *table_slots(PyObject *self, PyObject *args)
{
    PyObject *o[3];
    if (!PyArg_ParseTuple(args, "OOO", &o[0], &o[1], &o[2]))
        return NULL;
    static const Spec spec[3] = {{"cell", 'q', 2, 0}, {"wanted", 'q', 2, 0}, {"out", 'q', 2, 1}};
    Arr a[3];
    if (take_all(o, a, spec, 3) < 0)
        return NULL;
    Arr cell = a[0], wanted = a[1], out = a[2];
    REQUIRE(cell.n[0] >= wanted.n[1] && out.n[0] == wanted.n[0] && out.n[1] == wanted.n[1]);
    Py_BEGIN_ALLOW_THREADS;
    for (Py_ssize_t q = 0; q < wanted.n[0]; q++) {
        for (Py_ssize_t i = 0; i < wanted.n[1]; i++) {
            int64_t c = E2(wanted, int64_t, q, i), found = -1;
            if (c >= 0) {
                for (Py_ssize_t j = 0; j < cell.n[1]; j++) {
                    if (E2(cell, int64_t, i, j) == c) {
                        found = j;
                        break;
                    }
                }
            }
            E2(out, int64_t, q, i) = found;
        }
    }
    Py_END_ALLOW_THREADS;
    release(a, 3);
    Py_RETURN_NONE;
}

/* table_values_at(snr_db, slot, out): Candidates.at, row i's SNR in slot slot[i], NaN
 * where slot[i] < 0. */
static PyObject *table_values_at(PyObject *self, PyObject *args)
{
    PyObject *o[3];
    if (!PyArg_ParseTuple(args, "OOO", &o[0], &o[1], &o[2]))
        return NULL;
    static const Spec spec[3] = {{"snr_db", 'd', 2, 0}, {"slot", 'q', 1, 0}, {"out", 'd', 1, 1}};
    Arr a[3];
    if (take_all(o, a, spec, 3) < 0)
        return NULL;
    Arr snr = a[0], slot = a[1], out = a[2];
    REQUIRE(snr.n[0] >= slot.n[0] && out.n[0] >= slot.n[0]);
    for (Py_ssize_t i = 0; i < slot.n[0]; i++) /* (a negative slot reads nothing) */
        REQUIRE(E1(slot, int64_t, i) < snr.n[1]);
    for (Py_ssize_t i = 0; i < slot.n[0]; i++) {
        int64_t s = E1(slot, int64_t, i);
        E1(out, double, i) = s >= 0 ? E2(snr, double, i, s) : NAN;
    }
    release(a, 3);
    Py_RETURN_NONE;
}

/* window_best(snr_bm, rows, best_db, window_db) -> n: the window tables of a search
 * without a floor (CandidateSearch._tables), first half: writes best_db of ``rows``
 * (the largest SNR of their pairs' beams, NaN ignored as np.fmax) and returns how many
 * beams are within ``window_db`` of their row's best (a comparison with NaN is false).
 * snr_bm (n_beam, m) the pairs' SNR [dB]; rows (m,) sorted (a row's pairs consecutive). */
static PyObject *window_best(PyObject *self, PyObject *args)
{
    PyObject *o[3];
    double window_db;
    if (!PyArg_ParseTuple(args, "OOOd", &o[0], &o[1], &o[2], &window_db))
        return NULL;
    static const Spec spec[3] = {{"snr_bm", 'd', 2, 0}, {"rows", 'q', 1, 0}, {"best_db", 'd', 1, 1}};
    Arr a[3];
    if (take_all(o, a, spec, 3) < 0)
        return NULL;
    Arr snr = a[0], rows = a[1], best_db = a[2];
    Py_ssize_t nb = snr.n[0], m = rows.n[0], n = 0;
    REQUIRE(snr.n[1] == m);
    INDICES(rows, 0, m, best_db.n[0]);
    Py_BEGIN_ALLOW_THREADS;
    Py_ssize_t p = 0;
    while (p < m) { /* the rows' best */
        Py_ssize_t q = p;
        int64_t row = E1(rows, int64_t, p);
        double top = NAN;
        while (q < m && E1(rows, int64_t, q) == row) {
            for (Py_ssize_t b = 0; b < nb; b++) {
                double v = E2(snr, double, b, q);
                if (top != top || v > top) /* np.fmax: a NaN loses */
                    top = v;
            }
            q++;
        }
        E1(best_db, double, row) = top;
        p = q;
    }
    for (p = 0; p < m; p++) {
        double low = E1(best_db, double, E1(rows, int64_t, p)) - window_db;
        for (Py_ssize_t b = 0; b < nb; b++)
            n += E2(snr, double, b, p) >= low;
    }
    Py_END_ALLOW_THREADS;
    release(a, 3);
    return PyLong_FromSsize_t(n);
}

/* window_fill(snr_bm, rows, sat, n_beam, window_db, best_db, out_row, out_cell, out_db):
 * the second half: (row, cell, snr_db) of every beam within the window, in (pair, beam)
 * order, into the outputs of the length window_best returned. */
static PyObject *window_fill(PyObject *self, PyObject *args)
{
    PyObject *o[7];
    Py_ssize_t n_beam;
    double window_db;
    if (!PyArg_ParseTuple(args, "OOOndOOOO", &o[0], &o[1], &o[2], &n_beam, &window_db, &o[3], &o[4],
                          &o[5], &o[6]))
        return NULL;
    static const Spec spec[7] = {{"snr_bm", 'd', 2, 0},  {"rows", 'q', 1, 0},
                                 {"sat", 'q', 1, 0},     {"best_db", 'd', 1, 0},
                                 {"out_row", 'q', 1, 1}, {"out_cell", 'q', 1, 1},
                                 {"out_db", 'd', 1, 1}};
    Arr a[7];
    if (take_all(o, a, spec, 7) < 0)
        return NULL;
    Arr snr = a[0], rows = a[1], sat = a[2], best_db = a[3], out_row = a[4], out_cell = a[5];
    Arr out_db = a[6];
    Py_ssize_t m = rows.n[0], cap = out_row.n[0], k = 0;
    REQUIRE(0 <= n_beam && n_beam <= snr.n[0] && snr.n[1] == m && sat.n[0] == m);
    REQUIRE(out_cell.n[0] == cap && out_db.n[0] == cap);
    INDICES(rows, 0, m, best_db.n[0]);
    Py_BEGIN_ALLOW_THREADS;
    for (Py_ssize_t p = 0; p < m; p++) {
        int64_t row = E1(rows, int64_t, p);
        double low = E1(best_db, double, row) - window_db;
        for (Py_ssize_t b = 0; b < n_beam; b++) {
            double v = E2(snr, double, b, p);
            if (v >= low && k < cap) {
                E1(out_row, int64_t, k) = row;
                E1(out_cell, int64_t, k) = E1(sat, int64_t, p) * n_beam + b;
                E1(out_db, double, k) = v;
                k++;
            }
        }
    }
    Py_END_ALLOW_THREADS;
    release(a, 7);
    return PyLong_FromSsize_t(k);
}

/* The first slot of row i of ``cell`` holding ``c`` (c >= 0), else -1: Candidates.slot_of. */
static inline int64_t slot_in(const Arr *cell, Py_ssize_t i, int64_t c)
{
    if (c < 0)
        return -1;
    for (Py_ssize_t j = 0; j < cell->n[1]; j++) {
        if (E2(*cell, int64_t, i, j) == c)
            return j;
    }
    return -1;
}

/* serving_column(cell, serving, n_beam, row0, pair_key, n_key, kx, ky, path_snr, visible,
 *                ix, iy, out_cell, out_snr, missing) -> (n_need, n_missing):
 * Decider._with_serving's column, UT by UT: where UT i's serving cell c >= 0 is not in
 * its table row (Candidates.slot_of), its pair (row0 + i, c // n_beam) is looked up among
 * the block's evaluated pairs (BlockCandidates.find_pairs: pair_key sorted, row * n_key +
 * sat); found and above the mask, out_cell = c and out_snr its beam's SNR,
 * (10 log10 k_x + 10 log10 k_y) + 10 log10 p as snr_kernel computes it; found below the
 * mask, -1 and NaN; not found, missing (the caller evaluates those pairs). n_need: the UTs
 * whose serving cell is not in their row. */
static PyObject *serving_column(PyObject *self, PyObject *args)
{
    PyObject *o[13];
    Py_ssize_t n_beam, row0, n_key;
    if (!PyArg_ParseTuple(args, "OOnnOnOOOOOOOOO", &o[0], &o[1], &n_beam, &row0, &o[2], &n_key,
                          &o[3], &o[4], &o[5], &o[6], &o[7], &o[8], &o[9], &o[10], &o[11]))
        return NULL;
    static const Spec spec[12] = {
        {"cell", 'q', 2, 0},     {"serving", 'q', 1, 0},   {"pair_key", 'q', 1, 0},
        {"kx", 'd', 2, 0},       {"ky", 'd', 2, 0},        {"path_snr", 'd', 1, 0},
        {"visible", '?', 1, 0},  {"ix", 'q', 1, 0},        {"iy", 'q', 1, 0},
        {"out_cell", 'q', 1, 1}, {"out_snr", 'd', 1, 1},   {"missing", '?', 1, 1}};
    Arr a[12];
    if (take_all(o, a, spec, 12) < 0)
        return NULL;
    if (n_beam < 1) {
        release(a, 12);
        PyErr_SetString(PyExc_ValueError, "leolink._kernels.serving_column: n_beam must be >= 1");
        return NULL;
    }
    Arr cell = a[0], serving = a[1], pair_key = a[2], kx = a[3], ky = a[4], path = a[5];
    Arr visible = a[6], ix = a[7], iy = a[8], out_cell = a[9], out_snr = a[10], missing = a[11];
    Py_ssize_t n = serving.n[0], m = pair_key.n[0], n_need = 0, n_missing = 0;
    REQUIRE(cell.n[0] >= n && out_cell.n[0] >= n && out_snr.n[0] >= n && missing.n[0] >= n);
    REQUIRE(kx.n[1] >= m && ky.n[1] >= m && path.n[0] >= m && visible.n[0] >= m);
    REQUIRE(ix.n[0] >= n_beam && iy.n[0] >= n_beam);
    INDICES(ix, 0, n_beam, kx.n[0]);
    INDICES(iy, 0, n_beam, ky.n[0]);
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t c = E1(serving, int64_t, i);
        E1(out_cell, int64_t, i) = -1;
        E1(out_snr, double, i) = NAN;
        E1(missing, char, i) = 0;
        if (c < 0 || slot_in(&cell, i, c) >= 0)
            continue;
        n_need++;
        int64_t sat = c / n_beam, beam = c % n_beam;
        int64_t key = (row0 + i) * n_key + sat, found = -1;
        if (sat < n_key) {
            Py_ssize_t lo = 0, hi = m; /* the first pair_key >= key */
            while (lo < hi) {
                Py_ssize_t mid = lo + (hi - lo) / 2;
                if (E1(pair_key, int64_t, mid) < key)
                    lo = mid + 1;
                else
                    hi = mid;
            }
            if (lo < m && E1(pair_key, int64_t, lo) == key)
                found = lo;
        }
        if (found < 0) {
            E1(missing, char, i) = 1;
            n_missing++;
            continue;
        }
        if (!E1(visible, char, found))
            continue;
        double snr = (10.0 * log10(E2(kx, double, E1(ix, int64_t, beam), found)) +
                      10.0 * log10(E2(ky, double, E1(iy, int64_t, beam), found))) +
                     10.0 * log10(E1(path, double, found));
        E1(out_cell, int64_t, i) = c;
        E1(out_snr, double, i) = snr;
    }
    release(a, 12);
    return Py_BuildValue("nn", n_need, n_missing);
}

/* find_pairs(pair_key, n_key, rows, sats, out): BlockCandidates.find_pairs, the index of
 * each pair (rows[i], sats[i]) among the block's evaluated pairs (pair_key: row * n_key +
 * sat, sorted ascending, unique), -1 where it was not evaluated or 0 <= sat < n_key fails.
 * Ascending queries (the monitor's: row after row) are found by galloping on from the last
 * one, O(n + m); others by bisection. Either finds the first key >= the query. */
static PyObject *find_pairs(PyObject *self, PyObject *args)
{
    PyObject *o[4];
    Py_ssize_t n_key;
    if (!PyArg_ParseTuple(args, "OnOOO", &o[0], &n_key, &o[1], &o[2], &o[3]))
        return NULL;
    static const Spec spec[4] = {{"pair_key", 'q', 1, 0}, {"rows", 'q', 1, 0},
                                 {"sats", 'q', 1, 0},     {"out", 'q', 1, 1}};
    Arr a[4];
    if (take_all(o, a, spec, 4) < 0)
        return NULL;
    Arr pair_key = a[0], rows = a[1], sats = a[2], out = a[3];
    REQUIRE(sats.n[0] == rows.n[0] && out.n[0] >= rows.n[0]);
    Py_ssize_t m = pair_key.n[0], at = 0;
    int64_t last = INT64_MIN;
    Py_BEGIN_ALLOW_THREADS;
    for (Py_ssize_t i = 0; i < rows.n[0]; i++) {
        int64_t sat = E1(sats, int64_t, i);
        if (sat < 0 || sat >= n_key) {
            E1(out, int64_t, i) = -1;
            continue;
        }
        int64_t key = E1(rows, int64_t, i) * n_key + sat;
        Py_ssize_t lo = 0, hi = m; /* the first index whose key >= key lies in [lo, hi] */
        if (key >= last) {         /* gallop from the last answer */
            lo = at;
            Py_ssize_t step = 1;
            hi = lo;
            while (hi < m && E1(pair_key, int64_t, hi) < key) {
                lo = hi + 1;
                hi = lo + step < m ? lo + step : m;
                step *= 2;
            }
        }
        while (lo < hi) {
            Py_ssize_t mid = lo + (hi - lo) / 2;
            if (E1(pair_key, int64_t, mid) < key)
                lo = mid + 1;
            else
                hi = mid;
        }
        at = lo;
        last = key;
        E1(out, int64_t, i) = lo < m && E1(pair_key, int64_t, lo) == key ? lo : -1;
    }
    Py_END_ALLOW_THREADS;
    release(a, 4);
    Py_RETURN_NONE;
}

/* ---- the summary's histograms (leolink.sim.histograms, leolink.io.summary.stats) ---- */

/* histogram_slots(values, lo, resolution, hi, n_bins, unserved, out): PercentileHistogram.slots,
 * the slot of every value: 0 below lo, 1 .. n_bins the bins, n_bins + 1 at or above hi (NaN
 * read as unserved); floor((x - lo) / resolution) as numpy computes it, clipped alike (a
 * value just below hi whose quotient rounds to n_bins is in slot n_bins + 1 on both). */
/* The slot of x (PercentileHistogram.slots, one value; x not NaN). */
static inline int64_t hist_slot(double x, double lo, double res, double hi, Py_ssize_t n_bins)
{
    double d = floor((x - lo) / res);
    d = x < lo ? -1.0 : (x >= hi ? (double)n_bins : d);
    d = d < -1.0 ? -1.0 : (d > (double)n_bins ? (double)n_bins : d);
    return (int64_t)d + 1;
}

static PyObject *histogram_slots(PyObject *self, PyObject *args)
{
    PyObject *o[2];
    double lo, res, hi, unserved;
    Py_ssize_t n_bins;
    if (!PyArg_ParseTuple(args, "OdddndO", &o[0], &lo, &res, &hi, &n_bins, &unserved, &o[1]))
        return NULL;
    static const Spec spec[2] = {{"values", 'd', 1, 0}, {"out", 'q', 1, 1}};
    Arr a[2];
    if (take_all(o, a, spec, 2) < 0)
        return NULL;
    Arr values = a[0], out = a[1];
    REQUIRE(out.n[0] >= values.n[0] && n_bins >= 0);
    Py_BEGIN_ALLOW_THREADS;
    for (Py_ssize_t i = 0; i < values.n[0]; i++) {
        double x = E1(values, double, i);
        E1(out, int64_t, i) = hist_slot(x != x ? unserved : x, lo, res, hi, n_bins);
    }
    Py_END_ALLOW_THREADS;
    release(a, 2);
    Py_RETURN_NONE;
}

/* db_stats_add(ut, values, count, total, pooled, p_lo, p_res, p_hi, p_nbins, g_lo, g_res,
 *              g_hi, g_nbins, keys) -> n_keys: DbStats.add of rows (ut[i], values[i]), the
 * finite values only, in their order: count[u] += 1 and total[u] += v (the running sum
 * of leolink.io.summary.stats.running_sum: the same additions in the same order), the
 * pooled histogram's count of the value's slot, and the value's key in the per-UT
 * histogram, u * (g_nbins + 2) + slot, into keys (its first n_keys entries). */
static PyObject *db_stats_add(PyObject *self, PyObject *args)
{
    PyObject *o[6];
    double p_lo, p_res, p_hi, g_lo, g_res, g_hi;
    Py_ssize_t p_nbins, g_nbins;
    if (!PyArg_ParseTuple(args, "OOOOOdddndddnO", &o[0], &o[1], &o[2], &o[3], &o[4], &p_lo,
                          &p_res, &p_hi, &p_nbins, &g_lo, &g_res, &g_hi, &g_nbins, &o[5]))
        return NULL;
    static const Spec spec[6] = {{"ut", 'q', 1, 0},    {"values", 'd', 1, 0},
                                 {"count", 'q', 1, 1}, {"total", 'd', 1, 1},
                                 {"pooled", 'q', 1, 1}, {"keys", 'q', 1, 1}};
    Arr a[6];
    if (take_all(o, a, spec, 6) < 0)
        return NULL;
    Arr ut = a[0], values = a[1], count = a[2], total = a[3], pooled = a[4], keys = a[5];
    Py_ssize_t n_keys = 0, g_slots = g_nbins + 2;
    REQUIRE(ut.n[0] >= values.n[0] && keys.n[0] >= values.n[0] && total.n[0] == count.n[0]);
    REQUIRE(p_nbins >= 0 && g_nbins >= 0 && pooled.n[0] >= p_nbins + 2);
    INDICES(ut, 0, values.n[0], count.n[0]);
    Py_BEGIN_ALLOW_THREADS;
    for (Py_ssize_t i = 0; i < values.n[0]; i++) {
        double v = E1(values, double, i);
        if (!isfinite(v))
            continue;
        int64_t u = E1(ut, int64_t, i);
        E1(count, int64_t, u) += 1;
        E1(total, double, u) += v;
        E1(pooled, int64_t, hist_slot(v, p_lo, p_res, p_hi, p_nbins)) += 1;
        E1(keys, int64_t, n_keys) = u * g_slots + hist_slot(v, g_lo, g_res, g_hi, g_nbins);
        n_keys++;
    }
    Py_END_ALLOW_THREADS;
    release(a, 6);
    return PyLong_FromSsize_t(n_keys);
}

/* ---- the controller's step (leolink.sim.handover.controller.step) ---- */

/* step_rules(cell, snr, target, serving, pending, pending_since, until, serving_since,
 *            in_outage, censored, serving_snr, t_s, min_snr, handover_s, ttt_s, tol,
 *            n_beam, o_serving, o_pending, o_since, o_until, o_serving_since, o_in_outage,
 *            o_censored, o_serving_snr, o_sat, o_beam, o_service, o_kind, o_new_db,
 *            o_last_db, o_closing) -> (n_bad, first_bad, n_events, n_closing)
 *
 * controller.step's rules for every UT, given the policy's target (the numpy code's
 * comparisons and selections, UT by UT: nothing is rounded but t_s + handover_s, which the
 * numpy code computes alike). The state's arrays in, the new state's out; per UT the event
 * kind (-1: none), the new serving cell's SNR and the old link's last (the event's
 * columns) and whether a dwell closes. n_bad: UTs whose target is not usable where one is
 * needed (the caller raises), first_bad the first of them (-1). */
static PyObject *step_rules(PyObject *self, PyObject *args)
{
    PyObject *o[26];
    double t_s, min_snr, handover_s, ttt_s, tol;
    Py_ssize_t n_beam;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOOOdddddnOOOOOOOOOOOOOOO", &o[0], &o[1], &o[2], &o[3],
                          &o[4], &o[5], &o[6], &o[7], &o[8], &o[9], &o[10], &t_s, &min_snr,
                          &handover_s, &ttt_s, &tol, &n_beam, &o[11], &o[12], &o[13], &o[14],
                          &o[15], &o[16], &o[17], &o[18], &o[19], &o[20], &o[21], &o[22], &o[23],
                          &o[24], &o[25]))
        return NULL;
    static const Spec spec[26] = {
        {"cell", 'q', 2, 0},           {"snr", 'd', 2, 0},          {"target", 'q', 1, 0},
        {"serving", 'q', 1, 0},        {"pending", 'q', 1, 0},      {"pending_since", 'd', 1, 0},
        {"until", 'd', 1, 0},          {"serving_since", 'd', 1, 0}, {"in_outage", '?', 1, 0},
        {"censored", '?', 1, 0},       {"serving_snr", 'd', 1, 0},  {"o_serving", 'q', 1, 1},
        {"o_pending", 'q', 1, 1},      {"o_since", 'd', 1, 1},      {"o_until", 'd', 1, 1},
        {"o_serving_since", 'd', 1, 1}, {"o_in_outage", '?', 1, 1}, {"o_censored", '?', 1, 1},
        {"o_serving_snr", 'd', 1, 1},  {"o_sat", 'q', 1, 1},        {"o_beam", 'q', 1, 1},
        {"o_service", 'b', 1, 1},      {"o_kind", 'b', 1, 1},       {"o_new_db", 'd', 1, 1},
        {"o_last_db", 'd', 1, 1},      {"o_closing", '?', 1, 1}};
    Arr a[26];
    if (take_all(o, a, spec, 26) < 0)
        return NULL;
    if (n_beam < 1) {
        release(a, 26);
        PyErr_SetString(PyExc_ValueError, "leolink._kernels.step_rules: n_beam must be >= 1");
        return NULL;
    }
    Arr cell = a[0], snr = a[1], target = a[2], serving = a[3], pending = a[4];
    Arr pending_since = a[5], until = a[6], serving_since = a[7], in_outage = a[8];
    Arr censored = a[9], serving_snr = a[10];
    Py_ssize_t n = target.n[0], n_bad = 0, first_bad = -1, n_events = 0, n_closing = 0;
    REQUIRE(cell.n[0] == n && snr.n[0] == n && snr.n[1] == cell.n[1]);
    for (int q = 3; q < N_ARR(a); q++) /* every other array: one value a UT */
        REQUIRE(a[q].n[0] == n);
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t old = E1(serving, int64_t, i), tgt = E1(target, int64_t, i);
        int was_out = E1(in_outage, char, i) != 0;
        double was_until = E1(until, double, i);
        int has_usable = 0; /* a finite SNR at or above the threshold */
        for (Py_ssize_t j = 0; j < snr.n[1]; j++) {
            double v = E2(snr, double, i, j);
            has_usable |= isfinite(v) && v >= min_snr;
        }
        int64_t slot_old = slot_in(&cell, i, old), slot_target = slot_in(&cell, i, tgt);
        int first = has_usable && old < 0 && !was_out;
        int interrupted = old >= 0 && t_s < was_until - tol;
        double target_db = slot_target >= 0 ? E2(snr, double, i, slot_target) : NAN;
        int target_ok = isfinite(target_db) && target_db >= min_snr;
        if (has_usable && !interrupted && !target_ok) {
            if (first_bad < 0)
                first_bad = i;
            n_bad++;
        }
        double current_db = slot_old >= 0 ? E2(snr, double, i, slot_old) : NAN;
        int immediate = !(isfinite(current_db) && current_db >= min_snr);
        int wants = has_usable && old >= 0 && !interrupted && tgt != old;
        int outage_start = !has_usable && !was_out;
        int outage_end = has_usable && was_out;
        double last = E1(serving_snr, double, i);
        double last_db = isfinite(current_db) ? current_db : last;
        /* what the rules give a UT that changes nothing (controller._unchanged) */
        int64_t new = old, p_out = -1;
        double since_out = NAN, new_db = current_db, o_until = was_until;
        double o_start = E1(serving_since, double, i);
        int o_out = was_out, o_cens = E1(censored, char, i) != 0;
        int kind = -1, closing = 0;
        if (wants || first || outage_start || outage_end) {
            /* time to trigger */
            int64_t p = wants && !immediate ? tgt : -1;
            int same = p >= 0 && p == E1(pending, int64_t, i);
            double since = same ? E1(pending_since, double, i) : (p >= 0 ? t_s : NAN);
            int waited = t_s - since >= ttt_s - tol;
            int handover = wants && (immediate || waited);
            int adopt = handover || outage_end || first;
            int dropped = adopt || outage_start;
            p_out = dropped ? -1 : (handover ? -1 : p);
            since_out = (dropped || handover || p < 0) ? NAN : since;
            new = adopt ? tgt : (outage_start ? -1 : old);
            int64_t slot_new = adopt ? slot_target : (outage_start ? -1 : slot_old);
            new_db = slot_new >= 0 ? E2(snr, double, i, slot_new) : NAN;
            if (handover)
                kind = (new / n_beam == old / n_beam) ? 0 : 1;
            if (outage_start)
                kind = 2;
            if (outage_end)
                kind = 3;
            closing = (handover || outage_start) && old >= 0;
            o_until = handover ? t_s + handover_s : (outage_start ? -INFINITY : was_until);
            o_start = adopt ? t_s : (outage_start ? NAN : o_start);
            o_out = (was_out && !outage_end) || outage_start;
            o_cens = first ? 1 : (adopt ? 0 : o_cens);
        }
        n_events += kind >= 0;
        n_closing += closing;
        /* serving_snr_db of the new state (controller._serving_db) */
        double kept = new == old ? last_db : NAN;
        E1(a[18], double, i) = new < 0 ? NAN : (isfinite(new_db) ? new_db : kept);
        E1(a[11], int64_t, i) = new;
        E1(a[12], int64_t, i) = p_out;
        E1(a[13], double, i) = since_out;
        E1(a[14], double, i) = o_until;
        E1(a[15], double, i) = o_start;
        E1(a[16], char, i) = (char)o_out;
        E1(a[17], char, i) = (char)o_cens;
        E1(a[19], int64_t, i) = new >= 0 ? new / n_beam : -1;
        E1(a[20], int64_t, i) = new >= 0 ? new % n_beam : -1;
        /* controller.service_codes: served, handover (executing), outage */
        int8_t code = 0;
        if (new >= 0 && t_s < o_until - tol)
            code = 1;
        if (o_out || new < 0)
            code = 2;
        E1(a[21], int8_t, i) = code;
        E1(a[22], int8_t, i) = (int8_t)kind;
        E1(a[23], double, i) = new_db;
        E1(a[24], double, i) = last_db;
        E1(a[25], char, i) = (char)closing;
    }
    release(a, 26);
    return Py_BuildValue("nnnn", n_bad, first_bad, n_events, n_closing);
}

/* ---- the visibility search (leolink.visibility) ---- */

/* FreeBSD msun e_asin.c (fdlibm 5.3; Copyright (C) 1993 by Sun Microsystems, Inc.:
 * "Permission to use, copy, modify, and distribute this software is freely granted,
 * provided that this notice is preserved"): pi/2 and pi/4 split in a high and a low part,
 * and the rational R(z) = P(z) / Q(z) of (asin(x) - x) / x**3 at z = x**2 on [0, 0.25]
 * (its Remez error < 2**-58.75). */
static const double PIO2_HI = 1.57079632679489655800e00, PIO2_LO = 6.12323399573676603587e-17;
static const double PIO4_HI = 7.85398163397448278999e-01;
static const double P0 = 1.66666666666666657415e-01, P1 = -3.25565818622400915405e-01;
static const double P2 = 2.01212532134862925881e-01, P3 = -4.00555345006794114027e-02;
static const double P4 = 7.91534994289814532176e-04, P5 = 3.47933107596021167570e-05;
static const double Q1 = -2.40339491173441421878e00, Q2 = 2.02094576023350569471e00;
static const double Q3 = -6.88283971605453293030e-01, Q4 = 7.70381505559019352791e-02;
/* 2**27 + 1: Veltkamp's splitter, whose high part of s has 26 bits (f * f is exact). */
static const double SPLIT = 134217729.0;

/* Arcsine of x in [-1, 1] [rad], fdlibm's method, every branch computed and one selected
 * (vectorizable); NaN stays NaN. |x| < 0.5: x + x R(x**2); else, with z = (1 - |x|) / 2
 * (exact) and s = sqrt(z), asin|x| = pi/2 - 2 (s + s R(z)): as is for |x| >= 0.975, else
 * with s = f + c split (f the high part of s) so that pi/4 - 2 f loses nothing. Within
 * 1 ulp of the C library's asin (tests/test_visibility.py). */
static inline double fdlibm_asin(double x)
{
    double a = fabs(x);
    int small = a < 0.5;
    double z_small = a * a, z_large = (1.0 - a) * 0.5; /* (both: selects, no branch) */
    double z = small ? z_small : z_large;
    double p = z * (P0 + z * (P1 + z * (P2 + z * (P3 + z * (P4 + z * P5)))));
    double q = 1.0 + z * (Q1 + z * (Q2 + z * (Q3 + z * Q4)));
    double r = p / q;
    double s = sqrt(z);
    double near_one = PIO2_HI - (2.0 * (s + s * r) - PIO2_LO);
    double hi = SPLIT * s;
    double f = hi - (hi - s);
    double c = (z - f * f) / (s + f);
    double middle = PIO4_HI - ((2.0 * s * r - (PIO2_LO - 2.0 * c)) - (PIO4_HI - 2.0 * f));
    double direct = a + a * r;
    double y = small ? direct : (a >= 0.975 ? near_one : middle);
    return copysign(y, x); /* asin(-0.0) = -0.0, as the C library's */
}

/* asin(x): fdlibm_asin of every value of a float64 array into another (its tests). */
static PyObject *asin_of(PyObject *self, PyObject *args)
{
    PyObject *o[2];
    if (!PyArg_ParseTuple(args, "OO", &o[0], &o[1]))
        return NULL;
    static const Spec spec[2] = {{"x", 'd', 1, 0}, {"out", 'd', 1, 1}};
    Arr a[2];
    if (take_all(o, a, spec, 2) < 0)
        return NULL;
    REQUIRE(a[1].n[0] >= a[0].n[0]);
    for (Py_ssize_t i = 0; i < a[0].n[0]; i++)
        E1(a[1], double, i) = fdlibm_asin(E1(a[0], double, i));
    release(a, 2);
    Py_RETURN_NONE;
}

/* The elevations of one site: row[k] = asin(n . d / |d|), d = r[:, p0 + k] - site. The
 * sums start from 0.0 as numpy's accumulators do; every lane does the same operations, so
 * neither the thread count nor the vector width changes a bit. Chunk by chunk, the sines
 * (sin_elevations) then their arcsines (asin_row): two small loops, each vectorized with
 * its constants in registers, 3.5 ns an elevation here against 6.5 as one loop. */
enum { ELEVATION_CHUNK = 256 };

VECTOR_CLONES static void sin_elevations(const double *restrict r0,
                                         const double *restrict r1,
                                         const double *restrict r2, Py_ssize_t n, double s0,
                                         double s1, double s2, double u0, double u1,
                                         double u2, double *restrict out)
{
    for (Py_ssize_t k = 0; k < n; k++) {
        double d0 = r0[k] - s0, d1 = r1[k] - s1, d2 = r2[k] - s2;
        double rho = sqrt(((0.0 + d0 * d0) + d1 * d1) + d2 * d2);
        double up = (((0.0 + d0 * u0) + d1 * u1) + d2 * u2) / rho;
        out[k] = up > 1.0 ? 1.0 : (up < -1.0 ? -1.0 : up); /* np.clip, keeps NaN */
    }
}

#define ELEVATION_ROW(T)                                                                  \
    VECTOR_CLONES static void asin_row_##T(const double *restrict x, Py_ssize_t n,        \
                                           T *restrict row)                               \
    {                                                                                     \
        for (Py_ssize_t k = 0; k < n; k++)                                                \
            row[k] = (T)fdlibm_asin(x[k]);                                                \
    }                                                                                     \
    static void elevation_row_##T(const double *r0, const double *r1, const double *r2,   \
                                  Py_ssize_t n_t, double s0, double s1, double s2,        \
                                  double u0, double u1, double u2, T *row)                \
    {                                                                                     \
        double up[ELEVATION_CHUNK];                                                       \
        for (Py_ssize_t lo = 0; lo < n_t; lo += ELEVATION_CHUNK) {                        \
            Py_ssize_t n = n_t - lo < ELEVATION_CHUNK ? n_t - lo : ELEVATION_CHUNK;       \
            sin_elevations(r0 + lo, r1 + lo, r2 + lo, n, s0, s1, s2, u0, u1, u2, up);     \
            asin_row_##T(up, n, row + lo);                                                \
        }                                                                                 \
    }
ELEVATION_ROW(double)
ELEVATION_ROW(float)

/* elevations(r, site, normal, out, t0, lo, hi): out[i, s, t0 + k] = asin(n_i . d / |d|),
 * d = r[:, s n_t + k] - site_i, for k < n_t = r.shape[1] / n_sat and the sites
 * lo .. hi - 1. r (3, n_sat n_t) satellite-major, C-contiguous; out (n_site, n_sat,
 * n_time) float64 or float32, C-contiguous (the whole result: the stores are unit-stride
 * runs, which the compiler vectorizes). */
static PyObject *elevations(PyObject *self, PyObject *args)
{
    PyObject *o[4];
    Py_ssize_t t0, lo, hi;
    if (!PyArg_ParseTuple(args, "OOOOnnn", &o[0], &o[1], &o[2], &o[3], &t0, &lo, &hi))
        return NULL;
    static const Spec spec[4] = {{"r", 'd', 2, 0}, {"site", 'd', 2, 0}, {"normal", 'd', 2, 0},
                                 {"out", 'F', 3, 1}};
    Arr a[4];
    if (take_all(o, a, spec, 4) < 0)
        return NULL;
    Arr r = a[0], site = a[1], normal = a[2], out = a[3];
    int f32 = kind_of(&out.view) == 'f';
    Py_ssize_t item = f32 ? 4 : 8;
    if (r.s[1] != 8 || out.s[2] != item || out.s[1] != out.n[2] * item ||
        out.s[0] != out.n[1] * out.s[1]) {
        release(a, 4);
        PyErr_SetString(PyExc_ValueError, "leolink._kernels.elevations: r's rows and out must "
                                          "be C-contiguous");
        return NULL;
    }
    Py_ssize_t n_sat = out.n[1], n_t = n_sat ? r.n[1] / n_sat : 0;
    ROWS(lo, hi, out.n[0]);
    REQUIRE(site.n[0] >= hi && site.n[1] >= 3 && normal.n[0] >= hi && normal.n[1] >= 3);
    REQUIRE(r.n[0] >= 3 && r.n[1] == n_sat * n_t && 0 <= t0 && t0 + n_t <= out.n[2]);
    Py_BEGIN_ALLOW_THREADS;
    const double *r0 = (const double *)r.p, *r1 = (const double *)(r.p + r.s[0]);
    const double *r2 = (const double *)(r.p + 2 * r.s[0]);
    for (Py_ssize_t i = lo; i < hi; i++) {
        double s0 = E2(site, double, i, 0), s1 = E2(site, double, i, 1);
        double s2 = E2(site, double, i, 2);
        double u0 = E2(normal, double, i, 0), u1 = E2(normal, double, i, 1);
        double u2 = E2(normal, double, i, 2);
        for (Py_ssize_t s = 0; s < n_sat; s++) {
            Py_ssize_t p0 = s * n_t;
            if (f32)
                elevation_row_float(r0 + p0, r1 + p0, r2 + p0, n_t, s0, s1, s2, u0, u1, u2,
                                    &E3(out, float, i, s, t0));
            else
                elevation_row_double(r0 + p0, r1 + p0, r2 + p0, n_t, s0, s1, s2, u0, u1, u2,
                                     &E3(out, double, i, s, t0));
        }
    }
    Py_END_ALLOW_THREADS;
    release(a, 4);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"links_kernel", links_kernel, METH_VARARGS, "The pair geometry and beam kernels."},
    {"dirichlet_kernels", dirichlet_kernels, METH_VARARGS, "array.dirichlet_kernels."},
    {"snr_kernel", snr_kernel, METH_VARARGS, "Links.snr_db_bm of the pairs lo .. hi - 1."},
    {"best_beam_kernel", best_beam_kernel, METH_VARARGS, "Links.best_beam of the pairs."},
    {"serve_kernel", serve_kernel, METH_VARARGS, "LinkEngine.serve_pairs, per row."},
    {"screen_ragged", screen_ragged, METH_VARARGS, "screening.screen_ragged, per UT row."},
    {"table_best", table_best, METH_VARARGS, "Candidates.best."},
    {"table_slots", table_slots, METH_VARARGS, "Candidates.slot_of."},
    {"table_values_at", table_values_at, METH_VARARGS, "Candidates.at."},
    {"window_best", window_best, METH_VARARGS, "The window tables' best and size."},
    {"window_fill", window_fill, METH_VARARGS, "The window tables' entries."},
    {"step_rules", step_rules, METH_VARARGS, "controller.step's rules, UT by UT."},
    {"histogram_slots", histogram_slots, METH_VARARGS, "PercentileHistogram.slots."},
    {"db_stats_add", db_stats_add, METH_VARARGS, "summary_stats.DbStats.add."},
    {"serving_column", serving_column, METH_VARARGS, "Decider._with_serving's column."},
    {"find_pairs", find_pairs, METH_VARARGS, "BlockCandidates.find_pairs."},
    {"asin_of", asin_of, METH_VARARGS, "fdlibm's arcsine of every value."},
    {"elevations", elevations, METH_VARARGS, "Elevations of sites x satellites x times."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_kernels",
                                    "leolink's compiled loops (leolink/engine/kernels.py).", -1,
                                    methods};

PyMODINIT_FUNC PyInit__kernels(void) { return PyModule_Create(&module); }
