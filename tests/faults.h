/* faults.h - a failing, counting allocator for the fault-injection test
 * (tests/test_faults.c): installed once through frep_set_allocator (frep.h), it numbers
 * every allocation of the library, makes allocation number N return NULL, and keeps
 * the blocks alive in a list, so leaks show without ASan (and name their allocation).
 * Environment: FREP_FAULT_TRACE=K prints the stack of allocation K of every run.
 */
#ifndef FREP_TEST_FAULTS_H
#define FREP_TEST_FAULTS_H

#include <stddef.h>
#include <stdio.h>

/* Route the library's allocations through the fault allocator. Call once, first. */
void fault_install(void);

/* Start a run: allocation counts start again from 1 and allocation number `fail_at`
 * (0: none) fails. Blocks leaked by earlier runs are not counted again (and are never
 * freed, so that LeakSanitizer reports them with their stacks at exit). */
void fault_arm(unsigned long fail_at);

/* Allocations (malloc, calloc and realloc calls) asked since fault_arm, the failed one
 * included. */
unsigned long fault_count(void);

/* 1 when the armed allocation was reached and failed. */
int fault_hit(void);

/* Blocks allocated since fault_arm and not freed yet. */
size_t fault_live(void);

/* 1 when the failed allocation was made inside the exported function `fn` (found by
 * dladdr: the test program is linked with -export-dynamic). */
int fault_failed_in(const char *fn);

/* Describe (as TAP comment lines "# ...") the stack of the failed allocation and the
 * allocation numbers of at most `max` blocks allocated since fault_arm and not freed.
 * Meant for the report of a failed check. */
void fault_report(FILE *f, size_t max);

#endif
