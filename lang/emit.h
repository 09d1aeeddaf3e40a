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

/* What emit_program met: the compiler reports each differently. */
typedef enum emit_status {
    EMIT_OK = 0,
    EMIT_NOMEM,          /* an allocation failed */
    EMIT_SLOTS,          /* more than FREP_MAX_SLOTS variable and temporary slots */
    EMIT_STACK,          /* a stack deeper than FREP_MAX_STACK */
    EMIT_BUG             /* an invariant of the emitter failed */
} emit_status;

/* Append the code of `lo` to p (p->nparams must already be set) and prog_finish()
 * it. Returns EMIT_OK, or why it failed. */
emit_status emit_program(const ir *g, const lowered *lo, frep_program *p);

#endif
