/* log1p.h - log1p of a block of values in one vectorized loop (fit/log1p.c), for the
 * Cauchy loss of fit/objective.c.
 */
#ifndef FREP_FIT_LOG1P_H
#define FREP_FIT_LOG1P_H

#include <stddef.h>

/* out[i] = log1p(q[i]) for n values q >= 0, to within 1 ulp (fdlibm's polynomial);
 * values above 2^1000, infinite, NaN or negative go through libm's log1p. */
void fit_log1p_block(size_t n, const double *q, double *out);

#endif
