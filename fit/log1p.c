/* log1p.c - log1p over a block of values for the robust losses of fit/objective.c.
 * Built with the point evaluators' flags (-fno-trapping-math, Makefile.am) so that the
 * selects below vectorize; libm's log1p is one call per point.
 *
 * The reduction and the polynomial are fdlibm's (as musl writes them):
 * Copyright (C) 1993 by Sun Microsystems, Inc. All rights reserved.
 * Developed at SunSoft, a Sun Microsystems, Inc. business.
 * Permission to use, copy, modify, and distribute this software is freely granted,
 * provided that this notice is preserved.
 */
#include "log1p.h"
#include "vm_internal.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

/* log1p(q) for 0 <= q <= FIT_LOG1P_MAX in plain arithmetic, so that a loop of it
 * vectorizes: fdlibm's log1p (u = 1 + q = 2^k m, m within
 * [sqrt(2)/2, sqrt(2)), log m from s = (m - 1)/(m + 1) by a degree-14 polynomial, the
 * rounding of 1 + q put back as c / u), with its branches turned into selects. */
#define FIT_LOG1P_MAX 0x1p1000
static inline __attribute__((always_inline)) double log1p_plain(double q)
{
    const double ln2_hi = 6.93147180369123816490e-01, ln2_lo = 1.90821492927058770002e-10,
                 Lg1 = 6.666666666666735130e-01, Lg2 = 3.999999999940941908e-01,
                 Lg3 = 2.857142874366239149e-01, Lg4 = 2.222219843214978396e-01,
                 Lg5 = 1.818357216161805012e-01, Lg6 = 1.531383769920937332e-01,
                 Lg7 = 1.479819860511658591e-01;
    double u = 1 + q;
    uint64_t iu, ie;
    memcpy(&iu, &u, sizeof iu);
    iu += 0x3ff0000000000000ULL - 0x3fe6a09e00000000ULL;
    /* k, the exponent of u rounded at sqrt(2), as a double: 2^52 + e - 2^52 */
    ie = (iu >> 52) | 0x4330000000000000ULL;
    double dk;
    memcpy(&dk, &ie, sizeof dk);
    dk -= 0x1p52 + 1023.0;
    /* both sides computed, then selected: no branch left in the loop */
    double c_hi = (1 - (u - q)) / u, c_lo = (q - (u - 1)) / u;
    double c = dk >= 54 ? 0 : dk >= 2 ? c_hi : c_lo;
    iu = (iu & 0x000fffffffffffffULL) + 0x3fe6a09e00000000ULL;
    double m;
    memcpy(&m, &iu, sizeof m);
    double f = m - 1, hfsq = 0.5 * f * f, s = f / (2 + f), z = s * s, w = z * z;
    double t1 = w * (Lg2 + w * (Lg4 + w * Lg6)), t2 = z * (Lg1 + w * (Lg3 + w * (Lg5 + w * Lg7)));
    return s * (hfsq + t1 + t2) + (dk * ln2_lo + c) - hfsq + f + dk * ln2_hi;
}

/* Compiled for AVX-512F, AVX2 and the baseline where GCC multi-versions (VM_CLONES). */
VM_CLONES
void fit_log1p_block(size_t n, const double *q, double *out)
{
    for (size_t i = 0; i < n; i++) out[i] = log1p_plain(q[i]);
    /* the few values the polynomial is not for: a second pass keeps the first free of
     * calls */
    for (size_t i = 0; i < n; i++)
        if (!(q[i] >= 0 && q[i] <= FIT_LOG1P_MAX)) out[i] = log1p(q[i]);
}

