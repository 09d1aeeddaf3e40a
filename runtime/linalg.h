/* linalg.h - small dense linear algebra of the shared base: the symmetric 3x3 eigen
 * decomposition (cyclic Jacobi) behind PCA normals and patches (geom/, segment/),
 * the dual-contouring QEF (mesh/) and oriented boxes (evolve/); the Cholesky
 * factorization and solves behind the fit's Levenberg-Marquardt steps and its
 * standard errors (fit/).
 */
#include <stddef.h>
#ifndef FREP_LINALG_H
#define FREP_LINALG_H

/* When the Jacobi iteration stops; each caller gives its own rule and its reason (the
 * rules were tuned with their callers, and outputs depend on the last bits). */
typedef struct linalg_jacobi_stop {
    int max_sweeps;    /* sweeps at most (one sweep rotates the pairs 01, 02, 12) */
    double off_below;  /* converged when off = |a01| + |a02| + |a12| < off_below ... */
    double off_rel;    /* ... or off <= off_rel * (|a00| + |a11| + |a22|); 0: not used */
    double pivot_below; /* a pair with |apq| < pivot_below is not rotated */
} linalg_jacobi_stop;

/* Eigen decomposition of the symmetric matrix a (not changed): a = v diag(w) v^T with
 * the eigenvectors as the columns of v, in no particular order. */
void linalg_sym3_jacobi(const double a[3][3], const linalg_jacobi_stop *stop, double w[3],
                        double v[3][3]);

/* The same for a row-major m (symmetrized as (m + m^T) / 2, exact on a symmetric m),
 * with ev ascending and eigenvector k in vec[3k .. 3k + 2]. */
void linalg_sym3_eig(const double m[9], const linalg_jacobi_stop *stop, double ev[3],
                     double vec[9]);

/* Cholesky factorization of the symmetric positive definite n x n row-major A in place:
 * its lower triangle becomes L with A = L L^T (the upper triangle is left as it was).
 * Returns 0, or -1 when A is not positive definite (A then partly overwritten). */
int linalg_cholesky(size_t n, double *A);

/* Solve L L^T x = b in place (b becomes x) with L from linalg_cholesky. */
void linalg_cholesky_solve(size_t n, const double *L, double *b);

#endif
