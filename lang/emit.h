/* emit.h - schedule lowered IR into postfix bytecode (lang/emit.c): the last stage of
 * the compiler, after lang/lower.c; its output runs on runtime/vm*.c.
 */
#ifndef FREP_EMIT_H
#define FREP_EMIT_H

#include "ir.h"
#include "lower.h"
#include "program.h"

/* Height of an expression emitted without a temporary, and stack it may need: a
 * deeper subexpression is computed first and kept in a temporary slot, so the
 * emitter's recursion and the VM stack stay bounded whatever the source. */
#define FREP_EMIT_MAX_HEIGHT 2000u
#define FREP_EMIT_MAX_NEED 64u
/* Parallel stores of more values than this go through temporaries instead of the
 * stack (a large array assigned inside a loop). */
#define FREP_EMIT_MAX_PARALLEL 16u

/* Append the code of `lo` to p (p->nparams must already be set) and prog_finish()
 * it. Returns 0, or -1 when out of memory or over a limit (slots, stack). */
int emit_program(const ir *g, const lowered *lo, frep_program *p);

#endif
