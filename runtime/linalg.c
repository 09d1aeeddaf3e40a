/* linalg.c - symmetric 3x3 eigen decomposition by cyclic Jacobi rotations
 * (runtime/linalg.h). Each rotation zeroes one off-diagonal pair; the sweeps converge
 * quadratically, so a few suffice and max_sweeps only bounds the loop.
 */
#include "linalg.h"

#include <math.h>
#include <string.h>

/* Rotate pair (p, q) of a by the Jacobi angle that zeroes a[p][q]; v accumulates. */
static void jacobi_rotate(double a[3][3], double v[3][3], int p, int q)
{
    double theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
    double t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
    double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
    for (int k = 0; k < 3; k++) { /* columns p, q */
        double akp = a[k][p], akq = a[k][q];
        a[k][p] = c * akp - s * akq;
        a[k][q] = s * akp + c * akq;
    }
    for (int k = 0; k < 3; k++) { /* rows p, q */
        double apk = a[p][k], aqk = a[q][k];
        a[p][k] = c * apk - s * aqk;
        a[q][k] = s * apk + c * aqk;
    }
    for (int k = 0; k < 3; k++) {
        double vkp = v[k][p], vkq = v[k][q];
        v[k][p] = c * vkp - s * vkq;
        v[k][q] = s * vkp + c * vkq;
    }
}

void linalg_sym3_jacobi(const double a0[3][3], const linalg_jacobi_stop *stop, double w[3],
                        double v[3][3])
{
    double a[3][3];
    memcpy(a, a0, sizeof a);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) v[i][j] = i == j;
    for (int sweep = 0; sweep < stop->max_sweeps; sweep++) {
        double off = fabs(a[0][1]) + fabs(a[0][2]) + fabs(a[1][2]);
        double diag = fabs(a[0][0]) + fabs(a[1][1]) + fabs(a[2][2]);
        if (off < stop->off_below || off <= stop->off_rel * diag) break;
        for (int p = 0; p < 2; p++)
            for (int q = p + 1; q < 3; q++)
                if (!(fabs(a[p][q]) < stop->pivot_below)) jacobi_rotate(a, v, p, q);
    }
    for (int i = 0; i < 3; i++) w[i] = a[i][i];
}

void linalg_sym3_eig(const double m[9], const linalg_jacobi_stop *stop, double ev[3],
                     double vec[9])
{
    double a[3][3], v[3][3], w[3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) a[i][j] = 0.5 * (m[3 * i + j] + m[3 * j + i]);
    linalg_sym3_jacobi((const double(*)[3])a, stop, w, v);
    int order[3] = {0, 1, 2};
    for (int i = 0; i < 2; i++)
        for (int j = i + 1; j < 3; j++)
            if (w[order[j]] < w[order[i]]) {
                int t = order[i];
                order[i] = order[j];
                order[j] = t;
            }
    for (int k = 0; k < 3; k++) {
        ev[k] = w[order[k]];
        for (int i = 0; i < 3; i++) vec[3 * k + i] = v[i][order[k]];
    }
}

int linalg_cholesky(size_t n, double *A)
{
    for (size_t j = 0; j < n; j++) {
        double s = A[j * n + j];
        for (size_t k = 0; k < j; k++) s -= A[j * n + k] * A[j * n + k];
        if (!(s > 0)) return -1;
        double l = sqrt(s);
        A[j * n + j] = l;
        for (size_t i = j + 1; i < n; i++) {
            double t = A[i * n + j];
            for (size_t k = 0; k < j; k++) t -= A[i * n + k] * A[j * n + k];
            A[i * n + j] = t / l;
        }
    }
    return 0;
}

void linalg_cholesky_solve(size_t n, const double *L, double *b)
{
    for (size_t i = 0; i < n; i++) {
        double t = b[i];
        for (size_t k = 0; k < i; k++) t -= L[i * n + k] * b[k];
        b[i] = t / L[i * n + i];
    }
    for (size_t i = n; i-- > 0;) {
        double t = b[i];
        for (size_t k = i + 1; k < n; k++) t -= L[k * n + i] * b[k];
        b[i] = t / L[i * n + i];
    }
}
