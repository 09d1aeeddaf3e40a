/* api_eval.c - interval evaluation in the public API: runtime/vm_interval.c's
 * enclosure of a program over a box, with its per-thread scratch.
 */
#include "config.h"

#include "api.h"
#include "interval.h"

#include <math.h>

frep_interval_scratch *frep_interval_scratch_new(const frep_program *p)
{
    return (frep_interval_scratch *)vm_iscratch_new(p);
}

void frep_interval_scratch_free(frep_interval_scratch *s)
{
    vm_iscratch_free((vm_iscratch *)s);
}

int frep_eval_interval(const frep_program *p, frep_interval_scratch *s, const double box[6],
                       const double *params, double *lo, double *hi)
{
    ival out = { -INFINITY, INFINITY };
    int rc = p && s && box ? vm_eval_interval(p, (vm_iscratch *)s, box, params, &out) : -1;
    *lo = out.lo;
    *hi = out.hi;
    return rc;
}
