# The modal sum Re(C e^{nu tau}) of a closed form's rows (included by _search.pyx and _phase.pyx): the
# reference is closed_form.Motion.evaluate's product (U @ e^{nu tau}).real and Phase._xi_at's. Each row is one
# sum over the terms in their order; four rows at a time (independent sums: they overlap in the pipeline,
# each rounds as it would alone).

cdef void modal_rows(const double* C, Py_ssize_t ld, Py_ssize_t row0, Py_ssize_t nrows, Py_ssize_t rowstep,
                     const double* er, const double* ei, Py_ssize_t es, Py_ssize_t p,
                     double* out) noexcept nogil:
    """out[q] = sum_m Re(C[row0 + q rowstep, m] (er[m es] + i ei[m es])) for q < nrows, m < p: C's rows are
    interleaved complex (ld doubles apart), the terms' values e^{nu_m tau} given by their real and imaginary
    parts (es doubles apart: 1 for two separate arrays, 2 for one interleaved array)."""
    cdef Py_ssize_t q = 0, m
    cdef double s0, s1, s2, s3, a, b
    cdef const double* c0
    cdef const double* c1
    cdef const double* c2
    cdef const double* c3
    while q + 4 <= nrows:
        c0 = &C[ld * (row0 + q * rowstep)]
        c1 = &C[ld * (row0 + (q + 1) * rowstep)]
        c2 = &C[ld * (row0 + (q + 2) * rowstep)]
        c3 = &C[ld * (row0 + (q + 3) * rowstep)]
        s0 = s1 = s2 = s3 = 0.0
        for m in range(p):
            a = er[m * es]
            b = ei[m * es]
            s0 = s0 + (c0[2 * m] * a - c0[2 * m + 1] * b)
            s1 = s1 + (c1[2 * m] * a - c1[2 * m + 1] * b)
            s2 = s2 + (c2[2 * m] * a - c2[2 * m + 1] * b)
            s3 = s3 + (c3[2 * m] * a - c3[2 * m + 1] * b)
        out[q] = s0
        out[q + 1] = s1
        out[q + 2] = s2
        out[q + 3] = s3
        q += 4
    while q < nrows:
        c0 = &C[ld * (row0 + q * rowstep)]
        s0 = 0.0
        for m in range(p):
            s0 = s0 + (c0[2 * m] * er[m * es] - c0[2 * m + 1] * ei[m * es])
        out[q] = s0
        q += 1
