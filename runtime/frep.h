/* frep.h - public interface of libfrep: compile HyperFun models to bytecode and
 * evaluate them over blocks of points.
 *
 * Rules of use:
 *  - A frep_program is immutable after frep_compile() and may be shared by threads.
 *  - A frep_scratch is per thread; never use one from two threads at once.
 *  - The library never prints: diagnostics go to the frep_diag_fn callback.
 *  - Every function that returns an allocation names the function that frees it;
 *    strings and arrays the library hands over are released with frep_free().
 *  - The allocator hook (frep_set_allocator) is the only process-wide state: set it
 *    before any other call, from one thread.
 */
#ifndef FREP_H
#define FREP_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define FREP_VERSION_STRING "0.1.0"

/* ---- memory ------------------------------------------------------------- */

/* An allocator: p NULL allocates n bytes, n 0 frees p, otherwise p is resized to n
 * bytes (contents kept, like realloc). Returns NULL when it cannot allocate; it is
 * never asked for 0 bytes. Called from any thread at once: it must be thread-safe. */
typedef void *(*frep_alloc_fn)(void *user, void *p, size_t n);

/* Route every allocation of the library through fn (NULL: the C library's malloc,
 * realloc and free). Install it before any other call of the library. */
void frep_set_allocator(frep_alloc_fn fn, void *user);

/* Release memory that the library handed to the caller (messages, disassembly,
 * model lists' arrays). NULL is ignored. */
void frep_free(void *p);

/* ---- diagnostics -------------------------------------------------------- */

typedef enum frep_severity { FREP_NOTE, FREP_WARNING, FREP_ERROR } frep_severity;

typedef struct frep_diag {
    frep_severity severity;
    const char *file;     /* may be NULL */
    uint32_t line, col;   /* 1-based; 0 when the diagnostic has no position */
    uint32_t len;         /* caret span length in columns (>= 1 when line > 0) */
    const char *message;  /* without "error: " prefix and without trailing newline */
} frep_diag;

typedef void (*frep_diag_fn)(void *user, const frep_diag *d);

/* Format a diagnostic GNU-style: "file:line:col: error: msg\n  <source line>\n  ^~~\n".
 * `source` (may be NULL) is the text the positions refer to. Returns a malloc'ed
 * string; frep_free() it. */
char *frep_diag_format(const frep_diag *d, const char *source, size_t source_len);

/* ---- compilation -------------------------------------------------------- */

typedef enum frep_setops {
    FREP_SETOPS_RFUNC = 0,  /* Rvachev R0 functions (HyperFun's default) */
    FREP_SETOPS_MINMAX,     /* min/max */
    FREP_SETOPS_RALPHA      /* R-alpha family with frep_compile_options.alpha */
} frep_setops;

typedef struct frep_compile_options {
    const char *model;      /* model to compile; NULL: "my_model" if present, else first */
    const double *a;        /* values of the a[] array (may be NULL: zeros) */
    size_t na;
    int setops_override;    /* -1: as the file says; else a frep_setops value */
    double alpha;           /* for FREP_SETOPS_RALPHA when overriding */
    int optimize;           /* constant folding + CSE (1, the default) or none (0) */
    int strict;             /* 1: what the reference interpreter rejects and frep
                               accepts (warnings "not HyperFun: ...") is an error */
} frep_compile_options;

void frep_compile_options_init(frep_compile_options *o);

typedef struct frep_program frep_program;

/* Compile `text` (len bytes, need not be NUL-terminated) read from `file` (a name for
 * diagnostics). Returns NULL after reporting errors through `diag`. Free with
 * frep_program_free(). Warnings may be reported on success too. */
frep_program *frep_compile(const char *file, const char *text, size_t len,
                           const frep_compile_options *opt, frep_diag_fn diag, void *user);
void frep_program_free(frep_program *p);

/* Names of the models in a file, in order (for --help and listings); NULL on parse
 * error (reported). Free the array and its strings with frep_free_strings(). */
char **frep_list_models(const char *file, const char *text, size_t len, size_t *count,
                        frep_diag_fn diag, void *user);
void frep_free_strings(char **v, size_t n);

/* Program queries. */
size_t frep_program_size(const frep_program *p);         /* instructions */
size_t frep_program_nparams(const frep_program *p);
const char *frep_program_param_name(const frep_program *p, size_t i);
double frep_program_param_value(const frep_program *p, size_t i);
/* Bounds (lo, hi) of parameter i; returns 1 when it has bounds, else 0. */
int frep_program_param_bounds(const frep_program *p, size_t i, double *lo, double *hi);
/* Model extent from an `-- @box` pragma; returns 1 and fills box[6] when known. */
int frep_program_box(const frep_program *p, double box[6]);

/* Write the disassembly to a malloc'ed string; frep_free() it. */
char *frep_disassemble(const frep_program *p);

/* ---- evaluation --------------------------------------------------------- */

typedef struct frep_scratch frep_scratch;

/* Per-thread evaluation state sized for `p` (and any program of at most the same
 * size). Free with frep_scratch_free(). NULL on allocation failure. */
frep_scratch *frep_scratch_new(const frep_program *p);
void frep_scratch_free(frep_scratch *s);

/* Runtime domain errors seen by a scratch since the last reset: the first (lowest
 * pc) error and the number of points that raised any. */
typedef struct frep_runtime_error {
    uint64_t count;         /* points with an error; 0: none */
    uint32_t pc;            /* instruction of the first error */
    const char *what;       /* "sqrt of a negative number", ... (static string) */
    double x, y, z;         /* a point that raised it */
} frep_runtime_error;
void frep_scratch_errors(const frep_scratch *s, frep_runtime_error *e);
void frep_scratch_reset_errors(frep_scratch *s);
/* Report an error through `diag` with the instruction's source position. */
void frep_report_runtime_error(const frep_program *p, const frep_runtime_error *e,
                               frep_diag_fn diag, void *user);

/* Evaluate at n points (x[i], y[i], z[i]) with parameter vector `params` (NULL: the
 * program's own values; else frep_program_nparams() values). Any n; internally in
 * blocks. Returns 0, or -1 on allocation failure / bad program. */
int frep_eval(const frep_program *p, frep_scratch *s, size_t n, const double *x,
              const double *y, const double *z, const double *params, double *f);

/* Values and gradient (forward-mode AD). gx/gy/gz may not be NULL. */
int frep_eval_grad(const frep_program *p, frep_scratch *s, size_t n, const double *x,
                   const double *y, const double *z, const double *params, double *f,
                   double *gx, double *gy, double *gz);

/* Values and derivatives with respect to the free parameters: dp[j*n + i] is
 * df(x_i)/dparam_j, for j < frep_program_nparams(p). */
int frep_eval_dparams(const frep_program *p, frep_scratch *s, size_t n, const double *x,
                      const double *y, const double *z, const double *params, double *f,
                      double *dp);

/* Parallel versions: OpenMP across blocks with one scratch per thread; results do not
 * depend on the thread count. `err` (may be NULL) receives the merged runtime
 * errors. nthreads <= 0: OpenMP's default. */
int frep_eval_par(const frep_program *p, size_t n, const double *x, const double *y,
                  const double *z, const double *params, double *f, int nthreads,
                  frep_runtime_error *err);
int frep_eval_grad_par(const frep_program *p, size_t n, const double *x, const double *y,
                       const double *z, const double *params, double *f, double *gx,
                       double *gy, double *gz, int nthreads, frep_runtime_error *err);

/* ---- attributes ---------------------------------------------------------
 * A model declared `name(x[3], a[M], s[K])` has K attributes: the values of its
 * s[] array (HyperFun's attributes: colours set with hfA_SetColor and the like) as
 * the model leaves them, after computing its value at the point.  s[] starts at 0,
 * statements write it, and a model called as `m(x, a, s)` hands its s[] back to the
 * caller (doc/language.md, "Attributes"). */

/* K, the size of the compiled model's s[]; 0 when it declares none. */
size_t frep_program_nattrs(const frep_program *p);

/* Attributes at n points: s[i * K + k] is s[k+1] at point i (K = nattrs, s holds
 * n * K values).  params, nthreads and err as frep_eval_par; a domain error in the
 * attribute computation gives NaN and is counted in err like a value's. Returns 0
 * (also when K is 0: nothing written), or -1 on allocation failure. */
int frep_eval_attrs_par(const frep_program *p, size_t n, const double *x, const double *y,
                        const double *z, const double *params, double *s, int nthreads,
                        frep_runtime_error *err);

#ifdef __cplusplus
}
#endif
#endif
