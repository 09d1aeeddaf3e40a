/* frep.h - public interface of libfrep: compile HyperFun models to bytecode, evaluate
 * them over blocks of points and over boxes, and do the jobs of the frep command from
 * a program: read and write point clouds, polygonize into indexed triangle meshes and
 * write and check them, sample surfaces, segment clouds into primitives, fit templates
 * to clouds, draw pictures, evolve construction trees.  doc/api.md is the guide;
 * every function declared here, and nothing else, is exported from libfrep.so.
 *
 * Rules of use:
 *  - A frep_program is immutable after frep_compile() and may be shared by threads.
 *  - A frep_scratch is per thread; never use one from two threads at once.
 *  - The library never prints: diagnostics go to the frep_diag_fn callback.
 *  - Every function that returns an allocation names the function that frees it;
 *    strings and arrays the library hands over are released with frep_free().
 *  - The allocator hook (frep_set_allocator) is the only process-wide state: set it
 *    before any other call, from one thread.
 *  - Progress and cancel callbacks of the long jobs (segment, fit, evolve) are called
 *    from the thread that called the job, never from the library's worker threads; a
 *    cancel keeps the best result so far.  Results (frep_fit, frep_evolution,
 *    frep_image, ...) are immutable once returned and may be read by several threads.
 */
#ifndef FREP_H
#define FREP_H

#include <signal.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- version ------------------------------------------------------------ */

/* The version this header belongs to (compile time); frep_version() is the version of
 * the library loaded at run time.  FREP_VERSION_NUMBER is MAJOR * 10000 + MINOR * 100
 * + PATCH, for #if. */
#define FREP_VERSION_MAJOR 0
#define FREP_VERSION_MINOR 1
#define FREP_VERSION_PATCH 0
#define FREP_VERSION_STRING "0.1.0"
#define FREP_VERSION_NUMBER \
    (FREP_VERSION_MAJOR * 10000 + FREP_VERSION_MINOR * 100 + FREP_VERSION_PATCH)

/* "MAJOR.MINOR.PATCH" of the library loaded (a static string). */
const char *frep_version(void);

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

/* Free parameters.  The parameter vector that frep_eval* take (`params`) holds
 * frep_program_nparams() values: first every element of the model's a[] array
 * (frep_program_na() of them, a[1] at index 0, whether the model reads them or not:
 * `my_model(x[3], a[1])` has one), then the named `-- @free` parameters in source
 * order (frep_program_nfree()).  So a model with one `r = 0.5; -- @free` and the
 * usual a[1] has two: never size the vector by counting the @free lines, ask
 * frep_program_param_index() where "r" is and frep_program_param_values() for the
 * whole vector. */
size_t frep_program_nparams(const frep_program *p);      /* na + nfree */
size_t frep_program_na(const frep_program *p);           /* elements of a[] */
size_t frep_program_nfree(const frep_program *p);        /* named @free parameters */
/* The index in the parameter vector of `name`: a named parameter as written ("r";
 * case-insensitive like every identifier) or an element of a[] ("a[2]", 1-based as
 * in the model).  Returns 0 and sets *index, or -1 when the model has no such
 * parameter. */
int frep_program_param_index(const frep_program *p, const char *name, size_t *index);
/* Copy the program's own values (from -a / frep_compile_options.a and the source)
 * into v[0..nparams-1], a vector to change and pass to frep_eval*.  n is v's length:
 * returns 0, or -1 (nothing written) when n < frep_program_nparams(p). */
int frep_program_param_values(const frep_program *p, double *v, size_t n);
/* Name ("a[2]" or as written), value and bounds of parameter i (an index of the
 * vector); NULL / NaN / 0 when i is out of range. */
const char *frep_program_param_name(const frep_program *p, size_t i);
double frep_program_param_value(const frep_program *p, size_t i);
/* Bounds (lo, hi) of parameter i; returns 1 when it has bounds, else 0. */
int frep_program_param_bounds(const frep_program *p, size_t i, double *lo, double *hi);
/* 1 when the program's code reads parameter i (an index of the vector), else 0 (also
 * for i out of range): an element of a[] the model never reads is 0 here, so a caller
 * can tell whether values of a[] matter (frep mesh's note "the model reads a[]"). */
int frep_program_param_used(const frep_program *p, size_t i);
/* Model extent from an `-- @box` pragma; returns 1 and fills box[6] when known. */
int frep_program_box(const frep_program *p, double box[6]);

/* The work budget: from now on, evaluations of p (its attribute programs included) may
 * run at most `limit` loop iterations in all, counted per point (a loop run 1000 times
 * at each of 1000 points counts 10^6; an iteration of the interval evaluator a mesher
 * uses on a box counts 64), whatever the thread count.  Past it, every
 * evaluation of a program with loops gives NaN with the runtime error "loop work over
 * the budget" (programs without loops still evaluate).  limit 0: no budget (the
 * default).  Setting a limit starts the count again at 0.  Returns 0, or -1 out of
 * memory.  Not while p is being evaluated. */
int frep_program_set_work_limit(frep_program *p, uint64_t limit);
/* The limit set (0: none), and the loop iterations counted since it was set. */
uint64_t frep_program_work_limit(const frep_program *p);
uint64_t frep_program_work_used(const frep_program *p);
/* 1 when the evaluations so far went over the budget (their results are NaN), else 0. */
int frep_program_work_spent(const frep_program *p);
/* A cancel flag (Ctrl-C, another thread): once *flag is non-zero, evaluations of p (its
 * attribute programs and the copies a mesher prunes from it included) stop their loops
 * within a few thousand iterations, giving NaN with the runtime error "loop stopped:
 * evaluation cancelled"; programs without loops evaluate as usual.  The caller checks
 * its flag and drops such results.  NULL: none (the default).  Returns 0, or -1 out of
 * memory.  Not while p is being evaluated. */
int frep_program_set_cancel(frep_program *p, volatile sig_atomic_t *flag);

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
 * program's own values; else frep_program_nparams() values, laid out as described
 * under "Free parameters" above). Any n; internally in blocks. Returns 0, or -1 on
 * allocation failure / bad program. */
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

/* Interval evaluation: an enclosure of f over a box.  A frep_interval_scratch is per
 * thread like frep_scratch (sized for `p` and any program of at most its size); free
 * with frep_interval_scratch_free(). NULL on allocation failure. */
typedef struct frep_interval_scratch frep_interval_scratch;
frep_interval_scratch *frep_interval_scratch_new(const frep_program *p);
void frep_interval_scratch_free(frep_interval_scratch *s);

/* [*lo, *hi] encloses f(x, y, z) over box = {x0, y0, z0, x1, y1, z1} (HyperFun's
 * order) with parameters `params` (NULL: the program's own): lo <= f <= hi at every
 * point of the box where no intermediate value is NaN.  Sound under rounding (one ulp
 * of widening per operation); [-inf, inf] when it cannot tell (branch conditions
 * undecided over the box, loops).  Returns 0, or -1 when the scratch is too small
 * for p. */
int frep_eval_interval(const frep_program *p, frep_interval_scratch *s, const double box[6],
                       const double *params, double *lo, double *hi);

/* ---- canonical source and grid summaries (frep print, frep eval --grid) -----
 * Added for the language and evaluation commands; they report like the jobs below
 * (errors through `diag` as FREP_ERROR, NULL or -1 returned). */

/* The canonical source of `text` (len bytes, read from `file`, a name for messages),
 * as `frep print` prints it: the same program (parsing it again gives the same tree),
 * laid out uniformly, annotations kept.  A syntax error is reported with its position
 * and gives NULL.  strict: check every model of the file first, as
 * frep_compile_options.strict does (its errors and warnings reported), and give NULL
 * when it has errors.  Returns a NUL-terminated string, *out_len its length (may be
 * NULL); frep_free() it.  May run in several threads at once. */
char *frep_print_source(const char *file, const char *text, size_t len, int strict,
                        size_t *out_len, frep_diag_fn diag, void *user);

/* Points per axis of a grid summary. */
#define FREP_GRID_MIN_N 2
#define FREP_GRID_MAX_N 4096        /* 4096^3 evaluations take hours already */

typedef struct frep_grid_options {
    long n;                 /* points per axis, FREP_GRID_MIN_N..FREP_GRID_MAX_N (64) */
    int has_box;            /* 1: box below; 0: the program's `-- @box`, else
                               [-10, 10]^3 (HyperFun's default) */
    double box[6];          /* x0, y0, z0, x1, y1, z1 */
    int prune;              /* evaluate each tile with a program shortened by interval
                               analysis (1); the values are the same either way */
    int single;             /* single precision where an error bound is certified, on
                               CPUs with AVX2 (0); inside and NaN counts stay exact */
    int nthreads;           /* <= 0: OpenMP's default */
} frep_grid_options;
void frep_grid_options_init(frep_grid_options *o);

/* The precision a grid was evaluated in (frep_grid_summary.precision). */
typedef enum frep_grid_precision {
    FREP_GRID_DOUBLE,          /* single precision not asked for */
    FREP_GRID_DOUBLE_NO_CPU,   /* asked for; the CPU lacks AVX2 */
    FREP_GRID_DOUBLE_NO_OPS,   /* asked for; the program has operations the float path
                                  lacks */
    FREP_GRID_SINGLE           /* float where certified: single_blocks, redone_blocks */
} frep_grid_precision;

/* What frep_eval_grid() found: every figure but `threads` the same at any thread
 * count and with or without pruning (min, max, sum within the float error bound of
 * double's with FREP_GRID_SINGLE). */
typedef struct frep_grid_summary {
    double box[6];             /* the box evaluated */
    uint64_t points;           /* n^3 */
    uint64_t inside;           /* values >= 0 */
    uint64_t nans;             /* NaN values */
    double min, max;           /* of the values but NaNs (infinities included) */
    double sum;                /* of the finite values, in a fixed order */
    double insns;              /* instructions x points evaluated */
    int threads;               /* threads it ran on */
    int precision;             /* a frep_grid_precision */
    uint64_t single_blocks;    /* blocks computed in float ... */
    uint64_t redone_blocks;    /* ... and of them again in double near the surface */
    frep_runtime_error errors; /* runtime domain errors (frep_report_runtime_error) */
} frep_grid_summary;

/* Evaluate p (its own parameters) at the n x n x n points x_i = x0 + (x1 - x0) i /
 * (n - 1) (likewise y, z) of the box and summarize the values into *s, in tiles of
 * 16^3 points with no buffer of values, as `frep eval --grid` does.  o NULL: the
 * defaults.  Runtime errors do not fail it: they are in s->errors (reported by the
 * caller); a work budget spent shows in frep_program_work_spent().  Returns 0, or -1
 * after reporting why (bad n, out of memory).  Several threads may evaluate the same
 * program at once. */
int frep_eval_grid(const frep_program *p, const frep_grid_options *o, frep_grid_summary *s,
                   frep_diag_fn diag, void *user);

/* ---- the jobs of the frep command ---------------------------------------- */
/* Functions below report why they fail through `diag` (may be NULL) as one
 * FREP_ERROR diagnostic whose message carries the position ("cloud.xyz:12: expected
 * 3 or 6 numbers, got 5") and no file/line fields, and return NULL or -1.  Warnings
 * (runtime domain errors of the model, NaN grid points) come the same way with
 * FREP_WARNING.  Files are written atomically: to a temporary in the same directory,
 * renamed over the path when complete.  All may run in several threads at once on
 * different objects; an object is not modified by any function taking it const. */

/* ---- point clouds ---- */

/* Points with optional normals, structure of arrays. */
typedef struct frep_cloud frep_cloud;

/* Read .xyz text (3 or 6 numbers a line) or PLY (ascii, binary; recognized by its
 * "ply" header), "-" for standard input.  Free with frep_cloud_free(). */
frep_cloud *frep_cloud_read(const char *path, frep_diag_fn diag, void *user);
/* A cloud of n points copied from x, y, z and, when nx is not NULL, the normals nx,
 * ny, nz (all three or none).  Free with frep_cloud_free(). */
frep_cloud *frep_cloud_new(size_t n, const double *x, const double *y, const double *z,
                           const double *nx, const double *ny, const double *nz,
                           frep_diag_fn diag, void *user);
void frep_cloud_free(frep_cloud *c);
size_t frep_cloud_size(const frep_cloud *c);
int frep_cloud_has_normals(const frep_cloud *c);
/* The cloud's own arrays (frep_cloud_size() values each; nx, ny, nz NULL without
 * normals), valid until frep_cloud_free().  Any pointer argument may be NULL. */
void frep_cloud_arrays(const frep_cloud *c, const double **x, const double **y,
                       const double **z, const double **nx, const double **ny,
                       const double **nz);
/* Write as `frep sample` does: PLY binary little endian (double x y z [nx ny nz])
 * when path ends in .ply, else .xyz text with %.17g (6 columns with normals); "-"
 * writes .xyz to standard output.  Returns 0 or -1. */
int frep_cloud_write(const frep_cloud *c, const char *path, frep_diag_fn diag, void *user);

/* ---- normals (frep normals) ---- */

/* Neighbourhood sizes of normal estimation: three points span a plane; the k-d tree
 * answers at most FREP_NORMALS_MAX_KNN nearest points a query. */
#define FREP_NORMALS_MIN_KNN 3
#define FREP_NORMALS_MAX_KNN 256

/* The checks the frep command makes of a cloud before estimating normals, segmenting
 * or evolving: coordinates within the range the geometry is exact in, at least 3
 * points, not all the same, not all on one line.  name names the cloud in the message
 * (NULL: "the cloud"): "part.xyz: all 12 points lie on one line".  Returns 0 with
 * *planar (may be NULL) set to 1 when all the points lie on one plane (they bound no
 * solid), else 0; or -1 after reporting why. */
int frep_cloud_check(const frep_cloud *c, const char *name, int *planar,
                     frep_diag_fn diag, void *user);

/* Settings of `frep normals` (doc/segment.md, "Normals"), defaults from
 * frep_normals_options_init().  The estimate is deterministic: no seed. */
typedef struct frep_normals_options {
    size_t knn;              /* neighbours of each plane fit, FREP_NORMALS_MIN_KNN..
                                FREP_NORMALS_MAX_KNN; 0: chosen from the cloud's noise
                                and spacing (the default, frep normals --knn auto) */
    int nthreads;            /* <= 0: OpenMP's default; the result does not depend on it */
    /* A flag a signal handler or another thread raises to stop the estimate (may be
     * NULL): polled on every thread at least every few thousand points. */
    volatile sig_atomic_t *cancel_flag;
} frep_normals_options;
void frep_normals_options_init(frep_normals_options *o);

/* What an estimate found and used; filled when not NULL. */
typedef struct frep_normals_info {
    size_t knn;              /* the neighbourhood size used */
    double spacing;          /* median distance of a point to its nearest other one */
    double noise;            /* standard deviation of the points off their surface */
    size_t components;       /* connected parts of the neighbour graph, each oriented */
    size_t flipped;          /* of those, turned over to face outward */
    int interrupted;         /* stopped by the cancel flag */
} frep_normals_info;

/* Estimate unit normals for every point of c in place, as `frep normals` (and frep
 * segment and frep evolve on a cloud without them): normals c has are replaced, a
 * cloud without gets them (frep_cloud_has_normals() is 1 afterwards).  Per point a
 * plane fitted to its knn nearest points with Gaussian weights, reweighted by its
 * residuals; oriented consistently along a minimum spanning tree of the neighbour
 * graph, each connected part outward, then checked patch by patch by the parity of
 * ray crossings.  o NULL: the defaults.  Returns 0; 1 when stopped by
 * o->cancel_flag (info->interrupted, no diagnostic: c's normals are then unfinished
 * and must not be used); -1 after reporting why (a cloud frep_cloud_check() refuses,
 * knn out of range, out of memory: c's normals are then unspecified). */
int frep_normals(frep_cloud *c, const frep_normals_options *o, frep_normals_info *info,
                 frep_diag_fn diag, void *user);

/* ---- triangle meshes ---- */

/* An indexed triangle mesh: vertices, optional unit vertex normals, triangles
 * counter-clockwise seen from outside. */
typedef struct frep_mesh frep_mesh;

/* Limits of polygonization (the same as the frep command's). */
#define FREP_MESH_MAX_GRID 2048   /* cells per axis */

typedef struct frep_mesh_options {
    double box[6];        /* x0, y0, z0, x1, y1, z1; used when has_box */
    int has_box;          /* 0: the program's `-- @box`, else [-10, 10]^3 (as frep mesh) */
    int grid;             /* cells per axis of the box, 1..FREP_MESH_MAX_GRID (64) */
    double iso;           /* the surface f = iso; inside is f >= iso (0) */
    const double *params; /* parameter vector (NULL: the program's own values) */
    int nthreads;         /* OpenMP threads, <= 0: the default; results do not depend on it */
    /* Called from one thread with the fraction done, 0..1 (may be NULL). */
    void (*progress)(void *user, double fraction);
    void *progress_user;
    /* What the frep command needs besides (frep mesh, sample and render run on this
     * API):  cells along x, y, z, each 1..FREP_MESH_MAX_GRID (HyperFun's -g NX,NY,NZ;
     * 0: grid on every axis, the default). */
    int grid_axes[3];
    /* A flag a signal handler or another thread raises to stop the job (may be NULL):
     * polled on every thread between blocks of points.  A stopped job returns NULL
     * (frep_polygonize() with info->interrupted set) and reports nothing, not even
     * the runtime errors of the points it had evaluated. */
    volatile sig_atomic_t *cancel_flag;
} frep_mesh_options;
void frep_mesh_options_init(frep_mesh_options *o);

/* What polygonization found and did (for summaries); filled when not NULL. */
typedef struct frep_mesh_info {
    double box[6];        /* the box used */
    int grid;
    size_t points_nan;    /* grid points where f is NaN, counted as outside */
    int touches_box;      /* the solid reaches the box: the mesh is closed by caps there */
    int full;             /* every grid point is inside: the mesh is the box */
    double seconds;       /* wall time */
    size_t octree_nodes, blocks, blocks_total, eval_points, grad_points, cells_split,
        face_vertices;    /* work done, as frep mesh -v prints it */
    size_t settled;       /* vertices moved onto the surface after the quads (-v) */
    /* wall time of the steps (frep mesh -v, doc/mesh.md): the octree, the blocks'
     * contouring, the quads, the assembly of the mesh, the settling of vertices */
    double octree_seconds, contour_seconds, quads_seconds, assembly_seconds,
        settle_seconds;
    int interrupted;      /* stopped by frep_mesh_options.cancel_flag */
} frep_mesh_info;

/* Polygonize f = iso by dual contouring on an interval-pruned octree (doc/mesh.md):
 * a closed, oriented mesh with normals from the gradient, as `frep mesh` makes it.
 * An empty mesh (no grid point inside, or info->full) is not an error.  Free with
 * frep_mesh_free(). */
frep_mesh *frep_polygonize(const frep_program *p, const frep_mesh_options *o,
                           frep_mesh_info *info, frep_diag_fn diag, void *user);

/* The model's colours at the vertices of m, as `frep mesh` writes them into PLY and
 * `frep render` draws them: s[1..3] of p (hfA_SetColor, ...) evaluated just inside the
 * surface near each vertex (one Newton step onto f = iso, at most a cell long, then a
 * thousandth of a cell inward), each clamped to [0, 1] and scaled to 0..255.  cell: the
 * mesh's smallest cell side.  On success returns 0 and sets *rgb to 3 bytes a vertex
 * (frep_free() it), or to NULL when p has fewer than 3 attributes (no colours); -1 out
 * of memory.  The evaluation's runtime errors go to *re (may be NULL; NaN colours
 * channel 0). */
int frep_mesh_colors(const frep_program *p, const frep_mesh *m, double cell, double iso,
                     const double *params, int nthreads, uint8_t **rgb, frep_runtime_error *re);

/* A mesh copied from nverts vertices v[3 * nverts], normals n (NULL: none) and ntris
 * triangles tri[3 * ntris] (0-based vertex indices, checked). */
frep_mesh *frep_mesh_new(size_t nverts, const double *v, const double *n, size_t ntris,
                         const uint32_t *tri, frep_diag_fn diag, void *user);
/* Read OFF, OBJ, STL (ascii, binary) or PLY (polygons split into fans). */
frep_mesh *frep_mesh_read(const char *path, frep_diag_fn diag, void *user);
void frep_mesh_free(frep_mesh *m);
size_t frep_mesh_nverts(const frep_mesh *m);
size_t frep_mesh_ntris(const frep_mesh *m);
/* The mesh's own arrays, valid until frep_mesh_free(): vertex i is v[3i..3i+2], its
 * normal n[3i..] (NULL when the mesh has none), triangle t tri[3t..3t+2]. */
const double *frep_mesh_vertices(const frep_mesh *m);
const double *frep_mesh_normals(const frep_mesh *m);
const uint32_t *frep_mesh_triangles(const frep_mesh *m);

typedef enum frep_mesh_format {
    FREP_MESH_AUTO = 0,   /* from the path's extension (.stl .obj .ply .off) */
    FREP_MESH_STL,        /* binary, or ascii */
    FREP_MESH_OBJ,
    FREP_MESH_PLY,        /* binary little endian, or ascii */
    FREP_MESH_OFF,
    FREP_MESH_WRL         /* VRML 2.0 (written only; colours as a Color node) */
} frep_mesh_format;
/* Write as `frep mesh` does ("-": standard output, STL unless fmt says).  ascii
 * selects text STL / PLY.  Returns 0 or -1. */
int frep_mesh_write(const frep_mesh *m, const char *path, frep_mesh_format fmt, int ascii,
                    frep_diag_fn diag, void *user);

/* `frep mesh --check`: a mesh is a closed, oriented 2-manifold when every count is 0
 * and the volume is > 0. */
typedef struct frep_mesh_check_result {
    size_t open_edges, nonmanifold_edges, flipped_edges, nonmanifold_verts, unused_verts,
        degenerate, nonfinite;
    double volume, area;          /* signed enclosed volume (positive when outward) */
    size_t self_intersections;    /* counted only when asked (slower) */
} frep_mesh_check_result;
/* Returns 0 with *r filled, or -1 (out of memory). */
int frep_mesh_check(const frep_mesh *m, int self_intersections, frep_mesh_check_result *r,
                    frep_diag_fn diag, void *user);

/* -- mesh files and checks of the frep command (frep mesh on this API) -- */

/* The format an output name's extension names (case-insensitive: .stl .obj .ply .off
 * .wrl); FREP_MESH_AUTO when it names none. */
frep_mesh_format frep_mesh_format_for_path(const char *path);
/* "STL", "OBJ", "PLY", "OFF", "VRML" (a static string; "unknown" for FREP_MESH_AUTO). */
const char *frep_mesh_format_name(frep_mesh_format fmt);
/* Write m to the open stream f as frep_mesh_write() writes a file (fmt not
 * FREP_MESH_AUTO), with vertex colours rgb (3 bytes a vertex, as frep_mesh_colors()
 * gives; NULL: none): PLY gets red, green, blue properties, VRML a Color node; STL,
 * OBJ and OFF carry none.  For callers that write atomically themselves.  Returns 0,
 * or -1 on a write error (errno says why; nothing is reported). */
int frep_mesh_write_stream(const frep_mesh *m, const uint8_t *rgb, FILE *f,
                           frep_mesh_format fmt, int ascii);

/* The bound of `frep mesh --check` on a vertex's distance from the surface, in cells:
 * dual contouring puts a vertex on the surface's tangent planes, so only a misplaced
 * vertex is this far. */
#define FREP_MESH_SURFACE_TOL 0.1
/* The vertices' distances from the surface f = iso, in cells (o's box and grid scaled
 * so that a cell is a unit cube): |f - iso| / |grad f|, or where that exceeds tol, the
 * smaller radius at which a search around the vertex reaches the other side. */
typedef struct frep_mesh_distance {
    double max_dist;      /* the largest distance */
    size_t worst;         /* a vertex that far */
    size_t far;           /* vertices farther than tol */
    size_t capped;        /* vertices on the box's faces (caps), not measured */
    size_t skipped;       /* vertices where f or grad f is NaN, not measured */
} frep_mesh_distance;
/* Measure m, polygonized from p with options o (NULL: the defaults; box, grid,
 * grid_axes, iso and params are read), against tol cells, as `frep mesh --check`.
 * Returns 0 with *r filled, or -1 after reporting why (out of memory). */
int frep_mesh_surface_distance(const frep_program *p, const frep_mesh_options *o,
                               const frep_mesh *m, double tol, frep_mesh_distance *r,
                               frep_diag_fn diag, void *user);

/* ---- sampling ---- */

/* The most points a sample holds (frep sample -n): keeps the cloud's arrays far from
 * SIZE_MAX. */
#define FREP_SAMPLE_MAX_POINTS ((size_t)1 << 28)

typedef struct frep_sample_options {
    size_t n;             /* points, outliers included (10000) */
    uint64_t seed;        /* the same seed gives the same cloud at any thread count (1) */
    double noise;         /* Gaussian position noise: standard deviation (0) ... */
    int noise_absolute;   /* ... times the box diagonal (0) or in model units (1) */
    double outliers;      /* fraction of the n points drawn uniformly in the box (0) */
    frep_mesh_options mesh; /* the model's box, iso, params, threads; grid 0 (the
                               default): chosen from n, 32..256, as frep sample */
} frep_sample_options;
void frep_sample_options_init(frep_sample_options *o);

/* Points on the surface f = iso with outward unit normals, as `frep sample`:
 * area-weighted on a fine mesh, projected by Newton steps; o NULL: the defaults.
 * Free with frep_cloud_free(). */
frep_cloud *frep_sample(const frep_program *p, const frep_sample_options *o,
                        frep_diag_fn diag, void *user);
/* Area-weighted points on a mesh's triangles with the face normals (o->mesh unused;
 * noise and outliers relative to the mesh's bounding box). */
frep_cloud *frep_sample_mesh(const frep_mesh *m, const frep_sample_options *o,
                             frep_diag_fn diag, void *user);

/* -- the frep command's sampling on this API -- */
/* Both samplers stop when o->mesh.cancel_flag is raised and return NULL without a
 * diagnostic (runtime errors of the model seen before are still reported). */

/* Write c to the open stream f as frep_cloud_write() writes the file `name` (PLY
 * when it ends in .ply, else .xyz text), for callers that write atomically
 * themselves.  Returns 0, or -1 on a write error (errno says why; nothing is
 * reported). */
int frep_cloud_write_stream(const frep_cloud *c, FILE *f, const char *name);

/* ---- segmentation (frep segment) ---- */

/* Primitive types, as bits of frep_segment_options.types. */
typedef enum frep_prim_type {
    FREP_PRIM_PLANE, FREP_PRIM_SPHERE, FREP_PRIM_CYLINDER, FREP_PRIM_CONE, FREP_PRIM_TORUS
} frep_prim_type;

/* frep_segment_options.min_points_small: no second detection phase. */
#define FREP_SEGMENT_NO_SMALL ((size_t)-1)

typedef struct frep_segment_options {
    double epsilon;        /* inlier distance; <= 0: 5x the measured noise, within
                              0.2-1% of the cloud's diagonal (doc/segment.md) */
    double cluster;        /* connectivity cell; <= 0: the default (doc/segment.md) */
    double normal_deg;     /* normal deviation allowed, degrees; <= 0: 25 */
    size_t min_points;     /* smallest support; 0: 1% of the points (at least 10) */
    size_t min_points_small; /* second phase's; 0: 0.04%; FREP_SEGMENT_NO_SMALL: no
                              second phase */
    double probability;    /* of missing no shape; <= 0: 0.99 */
    unsigned types;        /* 1u << FREP_PRIM_* bits; 0: all */
    uint64_t seed;         /* the same seed gives the same result at any thread count (1) */
    int nthreads;          /* <= 0: OpenMP's default */
    size_t knn;            /* neighbours for normal estimation; 0: the default */
    int separating;        /* add the separating primitives (1) */
    /* Called from the calling thread as detection goes (may be NULL): the stage
     * ("normals", "detect", then "merge" per pair of redundant primitives tried),
     * points assigned of total, primitives so far. */
    void (*progress)(void *user, const char *stage, size_t done, size_t total, size_t nprims);
    /* Polled at every step (may be NULL): nonzero stops detection, and the result
     * holds what was found (frep_segmentation_interrupted() is then 1). */
    int (*cancel)(void *user);
    void *user;            /* for progress and cancel */
    /* A flag a signal handler or another thread raises to stop as cancel does (may be
     * NULL): polled at every step of detection and on every thread of the normal
     * estimation.  When given, a cancel callback saying stop raises it. */
    volatile sig_atomic_t *cancel_flag;
} frep_segment_options;
void frep_segment_options_init(frep_segment_options *o);

/* The primitives found in a cloud: fitted ones first, then separating ones. */
typedef struct frep_segmentation frep_segmentation;

/* Efficient RANSAC over c, as `frep segment` (doc/segment.md).  c's normals are
 * estimated (and stored in c) as frep_normals() does, with o's knn, threads and
 * cancel flag, when it has none (knn 0: from the data) or when some are zero (then
 * knn 0 means 12 neighbours).  A cancel during the estimate gives a segmentation
 * without primitives, interrupted.  Free the result with frep_segmentation_free(). */
frep_segmentation *frep_segment(frep_cloud *c, const frep_segment_options *o,
                                frep_diag_fn diag, void *user);
void frep_segmentation_free(frep_segmentation *s);
size_t frep_segmentation_nprims(const frep_segmentation *s);     /* all primitives */
size_t frep_segmentation_nfitted(const frep_segmentation *s);    /* fitted ones */
size_t frep_segmentation_unassigned(const frep_segmentation *s); /* points in none */
int frep_segmentation_interrupted(const frep_segmentation *s);
/* The settings a segmentation used (defaults resolved) and what it found. */
typedef struct frep_segment_info {
    size_t npoints;          /* of the cloud (0 for primitives read from a file) */
    size_t nprims, nfitted, unassigned;
    double diagonal;         /* of the cloud's bounding box: the scale of the output */
    double noise;            /* measured noise (0 when epsilon was given) */
    double epsilon, cluster, normal_deg, probability;
    size_t min_points;
    size_t min_points_small; /* == min_points: no second phase */
    int normals_estimated;   /* 1: c's normals were estimated (none, or zero ones) */
    size_t zero_normals;     /* zero-length normals found in the cloud */
    size_t draws;            /* candidate shapes drawn */
    int interrupted;
} frep_segment_info;
void frep_segmentation_get_info(const frep_segmentation *s, frep_segment_info *info);

/* Names of the primitive types ("plane", "sphere", "cylinder", "cone", "torus", as in
 * .fit files and frep segment --types); NULL for a value out of range. */
#define FREP_PRIM_NTYPES 5
const char *frep_prim_type_name(int type);

/* A primitive surface, inside where its signed distance is >= 0 (doc/segment.md). */
typedef struct frep_prim {
    int type;                /* a frep_prim_type */
    double p[3];             /* plane: unit outward normal; sphere: centre; cylinder:
                                a point of the axis; cone: apex; torus: centre */
    double a[3];             /* cylinder, cone, torus: unit axis (else 0) */
    double r;                /* plane: offset d (f = d - n.x); sphere, cylinder: radius;
                                cone: half-angle (radians); torus: minor radius */
    double R;                /* torus: major radius */
    int separating;          /* added to separate the others, not fitted */
    size_t support;          /* inliers (0 for a separating primitive) */
    double rms;              /* RMS distance of the inliers */
} frep_prim;
/* Primitive j < frep_segmentation_nprims(s): returns 0, or -1 when j is out of range. */
int frep_segmentation_get_prim(const frep_segmentation *s, size_t j, frep_prim *p);

/* v in the fewest significant digits that stay within quantum / 2 of it, as frep
 * segment's summary and the .hf files print numbers ("0" when |v| is below that;
 * quantum <= 0: the shortest form that reads back exactly), into buf of size bytes
 * (FREP_NUMBER_BUF is always enough).  Returns buf. */
#define FREP_NUMBER_BUF 32
char *frep_format_number(char *buf, size_t size, double v, double quantum);

/* Per point of the cloud (its size at frep_segment()): the index of its fitted
 * primitive, or -1; valid until frep_segmentation_free(). */
const int32_t *frep_segmentation_labels(const frep_segmentation *s);
/* Write the primitives as `frep segment -o` does: a .fit list when path ends in
 * .fit, else a .hf model with `header` (may be NULL) as its comment lines. */
int frep_segmentation_write(const frep_segmentation *s, const char *path, const char *header,
                            frep_diag_fn diag, void *user);

/* ---- fitting (frep fit) ---- */

typedef enum frep_fit_method {
    FREP_FIT_SAQN,        /* simulated annealing, then quasi-Newton (the default) */
    FREP_FIT_QN,          /* quasi-Newton from the start values */
    FREP_FIT_SA,          /* annealing only */
    FREP_FIT_LM           /* Levenberg-Marquardt from the start values */
} frep_fit_method;
typedef enum frep_fit_objective {
    FREP_FIT_ALGEBRAIC,   /* residual f(x_i) */
    FREP_FIT_GEOMETRIC    /* residual f / |grad f| */
} frep_fit_objective;
typedef enum frep_fit_loss {
    FREP_FIT_L2, FREP_FIT_HUBER, FREP_FIT_CAUCHY, FREP_FIT_GEMAN
} frep_fit_loss;
/* The names `frep fit` spells them with (--method saqn|qn|sa|lm, --objective
 * algebraic|geometric, --loss l2|huber|cauchy|geman; doc/fit.md): _name gives the
 * name of a value (a static string; NULL for a value outside the enum), _parse the
 * value of a name (exact, lower case): 0 with *out set, or -1 (*out untouched). */
const char *frep_fit_method_name(frep_fit_method m);
int frep_fit_method_parse(const char *name, frep_fit_method *out);
const char *frep_fit_objective_name(frep_fit_objective k);
int frep_fit_objective_parse(const char *name, frep_fit_objective *out);
const char *frep_fit_loss_name(frep_fit_loss l);
int frep_fit_loss_parse(const char *name, frep_fit_loss *out);

/* What the progress callback gets, at most every 0.2 s. */
typedef struct frep_fit_progress {
    int phase;            /* 0 annealing, 1 quasi-Newton, 2 Levenberg-Marquardt */
    long chain, nchains;  /* annealing chain (from 1); 0 in a local-only fit */
    long iteration;       /* of the phase */
    double best;          /* lowest objective so far of the kind being minimized */
    int subset;           /* best is on: 0 all points, 1 the annealing's subset, 2 the
                             robust refinement's loss */
    double elapsed;       /* seconds since the fit started */
} frep_fit_progress;

/* Every setting of `frep fit` (doc/fit.md), defaults from frep_fit_options_init(). */
typedef struct frep_fit_options {
    frep_fit_method method;          /* FREP_FIT_SAQN */
    frep_fit_objective objective;    /* local phase's: FREP_FIT_ALGEBRAIC */
    frep_fit_objective global_objective; /* the annealing's: FREP_FIT_ALGEBRAIC */
    frep_fit_loss loss;              /* FREP_FIT_L2 */
    double loss_scale;               /* <= 0: 1% of the cloud's diagonal */
    frep_fit_loss sa_loss;           /* the annealing's loss with robust (FREP_FIT_L2,
                                        Geman-McClure on a cloud with over 0.5% isolated
                                        points: doc/fit.md) */
    int robust;                      /* robust refinement after the local phase (1) */
    double normals_weight;           /* normal-agreement term; > 0 needs normals (0) */
    uint64_t seed;                   /* same seed, same result at any thread count (1) */
    double max_time;                 /* seconds; 0: no limit */
    long max_evals;                  /* objective evaluations; 0: no limit */
    uint64_t max_work;               /* loop iterations of the template's evaluations,
                                        summed over the points (frep_program_set_work_limit);
                                        0: no budget */
    size_t sa_points;                /* points the annealing uses (1024; 0: all) */
    long sa_stall, sa_chains;        /* annealing stall iterations (15), chains (2) */
    double sa_threshold;             /* leave the annealing at this objective (-inf) */
    int nthreads;                    /* <= 0: OpenMP's default */
    /* Bounds of a[] for a template without `-- @free` (nbounds == its a[] size, or 0:
     * none); a template with @free parameters carries its own bounds. */
    const double *lo, *hi;
    size_t nbounds;
    /* Called from the calling thread (may be NULL). */
    void (*progress)(void *user, const frep_fit_progress *p);
    /* Polled with the progress and between evaluations (at most every 0.02 s there;
     * may be NULL): nonzero stops the fit, which keeps the best parameters so far
     * (frep_fit_info.interrupted), left unmeasured (rms and max NaN). */
    int (*cancel)(void *user);
    void *user;                      /* for progress and cancel */
} frep_fit_options;
void frep_fit_options_init(frep_fit_options *o);

/* A finished fit: the fitted parameters, the measures and the fitted template. */
typedef struct frep_fit frep_fit;

/* Fit the free parameters of the template `text` (len bytes, called `file` in
 * messages, compiled with copt, NULL: the defaults) to the points of c, as `frep fit`:
 * the `-- @free` parameters when there are any, else the elements of a[] that the
 * model reads (started from copt->a).  c's normals are scaled to unit length in place.
 * Notes (an unbounded parameter's search range) and the parameters' warnings
 * (frep_fit_param.warnings) come through diag as FREP_NOTE / FREP_WARNING; compiler
 * diagnostics carry the file and position.  Free with frep_fit_free(). */
frep_fit *frep_fit_template(const char *file, const char *text, size_t len,
                            const frep_compile_options *copt, frep_cloud *c,
                            const frep_fit_options *o, frep_diag_fn diag, void *user);
void frep_fit_free(frep_fit *f);

/* Warnings about a fitted parameter, bits of frep_fit_param.warnings. */
#define FREP_FIT_ON_BOUND 1      /* within 1e-6 of its range from a bound */
#define FREP_FIT_NEAR_BOUND 2    /* within 1% of its range from a bound */
#define FREP_FIT_NO_EFFECT 4     /* the surface does not move with it */
#define FREP_FIT_TINY_EFFECT 8   /* its whole range moves the surface by < 1e-6 diagonal */
#define FREP_FIT_LOOSE 16        /* standard error above 5% of its range */

typedef struct frep_fit_param {
    const char *name;     /* "r" or "a[2]", valid until frep_fit_free() */
    size_t index;         /* in the program's parameter vector */
    double start, value, lo, hi;
    double sigma;         /* standard error (NaN when unknown) */
    double sensitivity;   /* RMS surface movement per unit (NaN when unknown) */
    unsigned warnings;    /* FREP_FIT_* bits */
} frep_fit_param;

typedef struct frep_fit_info {
    size_t npoints, nparams;       /* points of the cloud, fitted parameters */
    double objective;              /* final objective on all points */
    double rms, max_dist;          /* true distances of the points to the surface */
    double within;                 /* share of points within 1% of the diagonal */
    double within_inliers;         /* the same among the points not taken for outliers */
    double diagonal, noise;        /* the cloud's diagonal; robust sigma of the distances */
    size_t outliers;
    long evals;                    /* objective evaluations */
    double seconds;                /* wall time (the one field that differs run to run) */
    int converged;                 /* the local phase passed its optimality test */
    int interrupted;               /* stopped by the cancel callback */
    const char *status;            /* "converged", "stopped", ... or "interrupted" */
    const char *verdict;           /* "good - 99.7% of points within 1% of the diagonal" */
} frep_fit_info;

size_t frep_fit_nparams(const frep_fit *f);
/* Parameter j < frep_fit_nparams(f); returns 0, or -1 when j is out of range. */
int frep_fit_get_param(const frep_fit *f, size_t j, frep_fit_param *p);
void frep_fit_get_info(const frep_fit *f, frep_fit_info *info);
/* The whole parameter vector of the template with the fitted values in place
 * (frep_program_nparams() of its program, as frep_eval* take it): returns 0, or -1
 * (nothing written) when n is smaller. */
int frep_fit_values(const frep_fit *f, double *v, size_t n);
size_t frep_fit_nvalues(const frep_fit *f);
/* The fitted template: the text with the fitted values in place of the old ones,
 * comments and layout kept, a `-- @box` around the cloud and, for an a[] template, a
 * `-- @params` line; valid until frep_fit_free(), *len its length (may be NULL). */
const char *frep_fit_text(const frep_fit *f, size_t *len);
/* Write the fitted template (as `frep fit -o path` does). Returns 0 or -1. */
int frep_fit_write(const frep_fit *f, const char *path, frep_diag_fn diag, void *user);
/* Write the report as `frep fit --json` does; template, cloud and output are the
 * names it quotes (may be NULL: ""). Returns 0 or -1. */
int frep_fit_write_json(const frep_fit *f, const char *path, const char *template_name,
                        const char *cloud_name, const char *output_name,
                        frep_diag_fn diag, void *user);

/* ---- pictures (frep render) ---- */

/* Limits of a picture (the PNG writer's). */
#define FREP_RENDER_MAX_SIDE 16384   /* pixels per side */

/* -- the views, for the frep command's option parsing (frep render on this API) -- */
/* The names frep_render_options.view takes, for messages. */
#define FREP_RENDER_VIEWS "iso, front, back, top, bottom, left, right, side"
/* 1 when view is one of FREP_RENDER_VIEWS, else 0. */
int frep_render_view_ok(const char *view);

typedef struct frep_render_options {
    int width, height;          /* pixels, 1..FREP_RENDER_MAX_SIDE (800 x 600) */
    const char *view;           /* iso, front, back, top, bottom, left, right, side ("iso") */
    /* A cloud drawn over the surface (may be NULL), each point coloured by its
     * distance to the surface: blue on it, red at `scale` or farther. */
    const frep_cloud *points;
    double scale;               /* <= 0: from the data (95th percentile, rounded up) */
    int plain;                  /* 1: do not colour the surface by its distance to the
                                   points (0) */
    /* The model the mesh comes from (may be NULL): the points' distances are then
     * |f - iso| / |grad f| (with the program's own parameters), else the distance to
     * the mesh's nearest triangle. */
    const frep_program *program;
    double iso;                 /* the surface f = iso (0) */
    int nthreads;               /* <= 0: OpenMP's default */
    /* Colours of the surface, red, green, blue 0..255 a vertex (frep_mesh_nverts()
     * x 3 bytes; may be NULL: grey), used when it is not coloured by distance. */
    const uint8_t *vertex_rgb;
} frep_render_options;
void frep_render_options_init(frep_render_options *o);

/* What a picture shows, for summaries; filled when not NULL. */
typedef struct frep_render_info {
    size_t ntris;               /* triangles drawn */
    size_t npoints;             /* points drawn */
    double mean_dist, max_dist; /* the points' finite |distance| to the surface */
    size_t inside, rings;       /* points inside the solid; as deep as drawn as rings */
    double point_scale, surface_scale; /* the colour scales used (0 without points) */
} frep_render_info;

/* An RGB picture: 3 bytes a pixel, rows from the top. */
typedef struct frep_image frep_image;

/* Draw m shaded, framed on it and the points, as `frep render` does (legends for the
 * distances).  Free with frep_image_free(). */
frep_image *frep_render(const frep_mesh *m, const frep_render_options *o,
                        frep_render_info *info, frep_diag_fn diag, void *user);
void frep_image_free(frep_image *img);
/* The pixels (width * height * 3 bytes), valid until frep_image_free(). */
const uint8_t *frep_image_pixels(const frep_image *img, int *width, int *height);
/* Write as PNG. Returns 0 or -1. */
int frep_image_write_png(const frep_image *img, const char *path, frep_diag_fn diag,
                         void *user);
/* Write img as PNG to the open stream f, as frep_image_write_png() writes a file, for
 * callers that write atomically themselves.  Returns 0, or -1 on a write error (errno
 * says why; nothing is reported). */
int frep_image_write_png_stream(const frep_image *img, FILE *f);

/* ---- a cloud against a surface (frep view, frep render) ---- */

/* How far a cloud is from a surface and the surface from the cloud: the colours of
 * frep view's page and frep render's points.  point[i] is the signed distance of
 * point i to the surface, > 0 inside: with a program, first-order |f - iso|/|grad f|
 * signed by f - iso (+-infinity where the gradient vanishes off the surface, 0 on
 * it), with the program's own parameters; without one, the distance to the nearest of
 * the mesh's triangles near it (a closed mesh file used as the model).  vertex[j] is
 * the distance of vertex j of the mesh to the nearest point: high where the surface
 * has no points, material the cloud does not show.  The scales are the distances
 * the colour scales map to their top, chosen from the data: the points' 95th
 * percentile of |point|, four times the vertices' median, each rounded up to 1, 2 or
 * 5 times a power of ten; 0 when no distance is finite and positive. */
typedef struct frep_distances {
    double *point;        /* frep_cloud_size() values */
    double *vertex;       /* frep_mesh_nverts() values */
    double point_scale, vertex_scale;
} frep_distances;
/* Measure cloud c against mesh m (polygonized from p, or NULL for a mesh file) with
 * nthreads OpenMP threads (<= 0: the default; the results do not depend on it).
 * Returns 0 with *d filled (free with frep_distances_free()), or -1 with *d empty
 * after reporting why (out of memory; a cloud with no points; a mesh without
 * triangles).  The model's runtime errors are reported as one warning with their
 * source position; those points' distances are NaN.  Safe to call from several
 * threads on the same program, mesh and cloud. */
int frep_cloud_distances(const frep_cloud *c, const frep_mesh *m, const frep_program *p,
                         double iso, int nthreads, frep_distances *d, frep_diag_fn diag,
                         void *user);
/* Free the arrays of d and empty it (d may be NULL or empty). */
void frep_distances_free(frep_distances *d);

/* ---- the page of frep view ---- */

/* What the page shows.  Every pointer may be NULL (that part is left out); the
 * scene only borrows them. */
typedef struct frep_view_scene {
    const char *name;          /* the model's file name: the title */
    const frep_mesh *mesh;
    const unsigned char *vrgb; /* frep_mesh_nverts() colours, red green blue 0..255:
                                  the model's s[1..3] (frep_mesh_colors()) */
    const double *vdist;       /* frep_mesh_nverts() distances of the surface to the
                                  cloud (frep_distances.vertex) */
    double vscale;             /* vdist mapped to the top of its colour scale (> 0) */
    size_t npoints;
    const double *px, *py, *pz;
    const double *pdist;       /* npoints signed distances to the surface, > 0 inside */
    double pscale;             /* |pdist| mapped to the top of its colour scale (> 0) */
    const char *source;        /* the model's text */
    size_t nparams;
    const char *const *pnames; /* nparams names and values of the free parameters */
    const double *pvalues;
    const char *diag;          /* messages of the compiler and the polygonizer (errors
                                  and warnings), file:line:col first */
    const char *cdiag;         /* messages about the cloud */
    int failed;                /* the last build failed: the mesh is an older one */
    const char *info;          /* one line: what was done (grid, timings) */
    const char *units;         /* what a distance is measured in ("model units") */
    unsigned version;          /* a served page reloads when it changes */
} frep_view_scene;
/* An empty scene (all NULL and 0). */
void frep_view_scene_init(frep_view_scene *s);
/* The page: one self-contained HTML file (the WebGL viewer with the scene inlined)
 * that opens from disk without a server or network; watch != 0 makes it ask the
 * server that sent it (frep_view_server) for new versions of /scene.json.  Returns the
 * text (frep_free() it) with its length in *len (may be NULL), or NULL after
 * reporting why (out of memory). */
char *frep_view_page(const frep_view_scene *s, int watch, size_t *len, frep_diag_fn diag,
                     void *user);
/* The page written to the open stream f (watch 0), for callers that write atomically
 * themselves.  Returns 0, or -1 after reporting why (out of memory, a write error). */
int frep_view_write_page(const frep_view_scene *s, FILE *f, frep_diag_fn diag, void *user);
/* The scene alone as the JSON object a watching page fetches (/scene.json).  Returns
 * the text (frep_free() it) with its length in *len (may be NULL), or NULL after
 * reporting why (out of memory). */
char *frep_view_scene_json(const frep_view_scene *s, size_t *len, frep_diag_fn diag,
                           void *user);

/* The loopback HTTP server of frep view --watch: 127.0.0.1 only, one poll(2) loop in
 * the calling thread, at most 16 clients each answered once (HTTP/1.0).  The caller
 * routes the path of each GET to a reply; unrouted paths get 404.  One server is used
 * by one thread at a time. */
typedef struct frep_view_reply {
    int status;                /* 200 (or 404: not found) */
    const char *type;          /* the content type */
    const char *body;          /* not copied: it must live until the route function is
                                  called again or the step returns */
    size_t len;
} frep_view_reply;
/* Fill *r for the path of a GET request (query string included); leaving *r as it is
 * answers 404. */
typedef void (*frep_view_route_fn)(void *user, const char *path, frep_view_reply *r);
typedef struct frep_view_server frep_view_server;
/* Listen on 127.0.0.1:port (0: any free port).  NULL after reporting why (the port is
 * taken, sockets fail, out of memory).  Close with frep_view_server_close(). */
frep_view_server *frep_view_server_open(int port, frep_diag_fn diag, void *user);
/* The port listened on. */
int frep_view_server_port(const frep_view_server *s);
/* Wait up to timeout_ms for the network, accept, read, answer the complete requests
 * through route, drop clients silent for 5 s.  Returns the number of requests
 * answered, or -1 when a signal interrupted the wait (the caller checks its flag). */
int frep_view_server_step(frep_view_server *s, int timeout_ms, frep_view_route_fn route,
                          void *user);
void frep_view_server_close(frep_view_server *s);   /* NULL is ignored */

/* ---- OpenSCAD source (frep export) ---- */

/* Facets of a full circle ($fn) by default: the round solids' facets then stay within
 * 0.5% of their radius (1 - cos(pi / 48) = 0.2%). */
#define FREP_SCAD_DEFAULT_FN 48
#define FREP_SCAD_MAX_FN 1024     /* OpenSCAD's meshes grow as $fn^2 for spheres */
typedef struct frep_scad_options {
    const char *model;     /* the model to export; NULL: my_model, else the last */
    const double *a;       /* values of a[] (missing: 0) */
    size_t na;
    double box[6];         /* the box frep mesh uses (x0 y0 z0 x1 y1 z1): unbounded
                              solids are cut by it, and it sizes the stand-ins of
                              infinite solids ([-10, 10]^3) */
    int fn;                /* $fn, 3..FREP_SCAD_MAX_FN (FREP_SCAD_DEFAULT_FN) */
    const char *title;     /* a first comment line (NULL: none) */
} frep_scad_options;
void frep_scad_options_init(frep_scad_options *o);
/* The model in src (len bytes; file names it in messages) as OpenSCAD source, as
 * `frep export` writes it (doc/export.md): constructive solid geometry of standard
 * solids, each named sub-expression a module.  Errors of the source and the construct
 * that has no OpenSCAD equivalent are reported at their position (file:line:col),
 * followed by one error without a position saying the export failed.  Returns the
 * text (frep_free() it), or NULL.  Reentrant. */
char *frep_export_scad(const char *file, const char *src, size_t len,
                       const frep_scad_options *o, frep_diag_fn diag, void *user);

/* ---- construction trees (frep evolve) ---- */

/* Limits of a run. */
#define FREP_EVOLVE_MAX_DEPTH 1024   /* frep_evolve_options.max_depth at most */

/* What a progress report is about (frep_evolve_progress.phase).  Reports of phases
 * FREP_EVOLVE_CLIQUES and later mark the start of a step: they carry no tree. */
typedef enum frep_evolve_phase {
    FREP_EVOLVE_GA,          /* a generation of a GA (the whole run's, or the polish) */
    FREP_EVOLVE_MERGE,       /* two clique trees merged (best_fitness NaN: a partial tree) */
    FREP_EVOLVE_MERGED,      /* the merged, simplified tree on the whole sample */
    FREP_EVOLVE_GROWN,       /* the merged tree after the growth steps */
    FREP_EVOLVE_CLIQUES,     /* the clique GAs of a partitioned run start */
    FREP_EVOLVE_SIMPLIFY,    /* the final tree's simplification starts */
    FREP_EVOLVE_NORMALS,     /* normal estimation starts (a cloud without normals) */
    FREP_EVOLVE_SEGMENT,     /* segmentation starts (no primitives given) */
    FREP_EVOLVE_SEARCH,      /* the search starts: primitives known, the clock of
                                elapsed, max_time's GA share and the trace set */
    FREP_EVOLVE_REFIT        /* the refit of the primitives' parameters starts (refit) */
} frep_evolve_phase;

typedef struct frep_evolve_progress {
    int phase;               /* a frep_evolve_phase */
    uint32_t generation;
    double best_fitness;     /* NaN while merging and in the start reports */
    uint32_t tree_size;      /* nodes of the best tree */
    size_t explained, npoints; /* scored points the best tree explains (with
                                report_explained; else 0 and 0) */
    double elapsed;          /* seconds since the search started (0 before) */
} frep_evolve_progress;

/* A model the evolved tree is joined to (frep evolve --residual MODEL): the tree is
 * evolved for the points the model explains poorly, with the model as one more leaf,
 * and the result's model file holds the model's source and the joined model
 * my_model. */
typedef struct frep_evolve_base frep_evolve_base;

/* The base from the program p and the text (len bytes) it was compiled from, called
 * `file` in messages; model: the model compiled (NULL: the default choice, as
 * frep_compile_options.model).  Its set operations must be min/max or R-functions.
 * p must outlive the base, and the base every evolution that uses it.  Free with
 * frep_evolve_base_free(). */
frep_evolve_base *frep_evolve_base_new(const frep_program *p, const char *file,
                                       const char *text, size_t len, const char *model,
                                       frep_diag_fn diag, void *user);
void frep_evolve_base_free(frep_evolve_base *b);
/* The set operations of the base's file: the evolved tree uses them whatever
 * frep_evolve_options.setops says. */
frep_setops frep_evolve_base_setops(const frep_evolve_base *b);

/* Every setting of `frep evolve` (doc/evolve.md), defaults from
 * frep_evolve_options_init(). */
typedef struct frep_evolve_options {
    uint64_t seed;           /* the same seed, the same tree at any thread count (1) */
    int nthreads;            /* <= 0: OpenMP's default */
    frep_setops setops;      /* FREP_SETOPS_MINMAX (the default) or FREP_SETOPS_RFUNC */
    uint32_t generations, stagnation, population, tournament, elite;
    double crossover, mutation, subtree_prob;
    int max_depth;           /* 0: ceil(log2 primitives) + 3; at most
                                FREP_EVOLVE_MAX_DEPTH */
    /* Seconds of wall time for the whole run from the call (0: no limit): segmentation
     * stops when it is spent (normal estimation does not), the search gets what is
     * left, and once it is spent the steps that only improve the tree (refit) are
     * skipped.  The same seed then gives a result that depends on the machine. */
    double max_time;
    int partition;           /* partition the primitives' overlap graph (1) */
    int polish;              /* after partitioning, a GA over all primitives (1) */
    uint32_t polish_stagnation;
    int simplify;            /* simplify the tree (1) */
    int support;             /* trim material no point supports (1) */
    size_t sample;           /* points the GA scores (4096; 0: all) */
    double epsilon;          /* distance tolerance, fraction of the diagonal (0.01) */
    double alpha_deg;        /* normal tolerance in degrees; <= 0: automatic */
    double lambda_scale;     /* size penalty per node, times ln(N) (1) */
    size_t knn;              /* neighbours for estimating normals; 0: from the data */
    int refit;               /* refine the tree's primitives together afterwards (0) */
    int report_explained;    /* fill frep_evolve_progress.explained (costs time) (0) */
    /* Called from the calling thread after each generation and merge, and at the
     * start of the steps (frep_evolve_phase; may be NULL). */
    void (*progress)(void *user, const frep_evolve_progress *p);
    /* Polled on the calling thread with each progress report and, in every phase but
     * normal estimation, at least every 0.1 s of work (at most every 10 ms; may be
     * NULL): nonzero stops the run, which keeps the best tree so far (a GA its best
     * tree, the clique GAs of a partitioned run the union of their trees, a merge or
     * a simplification the tree as it stands) and skips the steps that only improve
     * it (frep_evolve_info.interrupted is then 1). */
    int (*cancel)(void *user);
    void *user;              /* for progress, cancel and trace */
    /* A flag a signal handler or another thread raises to stop the run as cancel does
     * (may be NULL): every phase polls it, normal estimation included, on every
     * thread, at least every 0.1 s of work.  When given, a cancel callback saying stop
     * raises it. */
    volatile sig_atomic_t *cancel_flag;
    /* The lines of `frep evolve --trace` (may be NULL; implies report_explained), each
     * with its newline, from the calling thread: four "#" header lines when the search
     * starts, one line per generation, merge and merged or grown tree ("generation wall
     * cpu fitness size explained% phase", wall and CPU seconds since the search
     * started, phase ga, merge, merged, grown or polish), and "# end: ..." when the run
     * is over (after the refit). */
    void (*trace)(void *user, const char *line);
    /* A GA (the whole run's, or the polish) ends once its best tree explains this
     * percentage of the scored points (time-to-solution measurements; implies
     * report_explained); 0: never (the default). */
    double stop_share;
    /* The model the tree is joined to (may be NULL: none); its setops replace setops. */
    const frep_evolve_base *base;
} frep_evolve_options;
void frep_evolve_options_init(frep_evolve_options *o);

/* An evolved construction tree over its primitives. */
typedef struct frep_evolution frep_evolution;

/* Primitives read from a .fit list or a .hf model written by frep segment (frep
 * evolve -p).  Free with frep_segmentation_free(); it has no labels (NULL). */
frep_segmentation *frep_segmentation_read(const char *path, frep_diag_fn diag, void *user);

/* Discover a construction tree of primitives whose zero set fits c, as `frep evolve`:
 * the primitives of prims (may be NULL: c is segmented with frep segment's defaults,
 * o's seed, threads and knn; with o->base, only the points the base explains poorly
 * are, and finding none is no error).  c's normals are estimated (stored in c) when it
 * has none.  Notes say what was done on the way (normals estimated, primitives
 * segmented, the base's share of the points, the refit's figures).  c must outlive the
 * result (writing the model checks it against the points).  Free with
 * frep_evolution_free(). */
frep_evolution *frep_evolve(frep_cloud *c, const frep_segmentation *prims,
                            const frep_evolve_options *o, frep_diag_fn diag, void *user);
void frep_evolution_free(frep_evolution *e);

typedef struct frep_evolve_info {
    uint32_t tree_size;      /* nodes */
    size_t nprims;           /* primitives the tree may use (the base not counted) */
    size_t npoints, dropped; /* valid points; points without finite coordinates/normal */
    size_t explained, within_eps, normals_ok; /* of npoints */
    double fitness;          /* on the scored sample */
    uint32_t generations;
    double seconds;
    double alpha_deg;        /* the normal tolerance used */
    int alpha_auto;          /* it was chosen from the noise */
    int partitioned, interrupted;
    double refit_rms_before, refit_rms_after; /* with refit (NaN otherwise) */
    /* The refit's other figures (0 and NaN without): parameters refined, largest
     * distance before and after, seconds. */
    size_t refit_nparams;
    double refit_max_before, refit_max_after, refit_seconds;
    /* The estimate behind an automatic alpha (valid when alpha_auto): the inliers'
     * robust position spread in epsilons, the median and 90th percentile of their
     * normals' deviation from the primitives' (degrees), the inliers counted, and
     * whether they were found noisy or faceted (the wider tolerance). */
    double noise_spread, noise_median_deg, noise_p90_deg;
    size_t noise_inliers;
    int noisy;
    /* With a base: the points it explains, and those where it cannot be evaluated. */
    size_t base_explained, base_failed;
} frep_evolve_info;
void frep_evolution_get_info(const frep_evolution *e, frep_evolve_info *info);

/* A cancel flag (Ctrl-C, another thread) the writers below poll while they round the
 * model's numbers and form its solids (seconds on large trees): once *flag is non-zero,
 * the numbers not yet checked are written as fitted and no further solid is formed,
 * so that the model is written at once (complete and valid).  NULL: none (the
 * default).  The flag must stay valid while e writes. */
void frep_evolution_set_cancel(frep_evolution *e, volatile sig_atomic_t *flag);

/* Write the model as `frep evolve -o` does; `command` and `cloud_name` go into its
 * comments (may be NULL), exact and hyperfun as --exact-numbers and --hyperfun. */
int frep_evolution_write(const frep_evolution *e, const char *path, const char *command,
                         const char *cloud_name, int exact, int hyperfun,
                         frep_diag_fn diag, void *user);
/* The same model as text (*len its length, may be NULL); frep_free() it.  NULL after
 * reporting why (out of memory). */
char *frep_evolution_model(const frep_evolution *e, const char *command,
                           const char *cloud_name, int exact, int hyperfun, size_t *len,
                           frep_diag_fn diag, void *user);
/* Write the tree for Graphviz (frep evolve --dot). */
int frep_evolution_write_dot(const frep_evolution *e, const char *path, frep_diag_fn diag,
                             void *user);
/* The same drawing as text, as frep_evolution_model(). */
char *frep_evolution_dot(const frep_evolution *e, size_t *len, frep_diag_fn diag, void *user);

#ifdef __cplusplus
}
#endif
#endif
