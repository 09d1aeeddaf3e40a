/* gp.h - the genetic-programming engine of `frep evolve` (Fayolle & Pasko, CAD 2016):
 * a population of construction trees over cached primitives, tournament selection,
 * subtree crossover and mutation, elitism; fitness evaluated in parallel.
 *
 * Runs on a gp_cache (fitness.h); called by evolve.c on all primitives and by
 * partition.c once per clique.  Results depend on the seed only, never on the number
 * of threads (all random choices are made serially; only scoring is parallel).
 */
#ifndef FREP_GP_H
#define FREP_GP_H

#include <signal.h>
#include <stdint.h>

#include "cancel.h"
#include "fitness.h"
#include "tree.h"

/* Defaults, from the paper unless noted. */
#define GP_DEFAULT_POPULATION 150
#define GP_DEFAULT_P_SUBTREE 0.7
#define GP_DEFAULT_P_CROSSOVER 0.3
#define GP_DEFAULT_P_MUTATION 0.3
#define GP_DEFAULT_ELITE 2
#define GP_DEFAULT_GENERATIONS 3000   /* the paper's longest runs */
#define GP_DEFAULT_TOURNAMENT 4       /* not in the paper: pressure that converges fast */
#define GP_DEFAULT_STAGNATION 40      /* generations without improvement before stopping */
/* Extra depth beyond a balanced tree of all primitives, room for complements and
 * subtractions (the default maximum depth is ceil(log2 k) + this). */
#define GP_DEPTH_SLACK 2
/* Fitness memo: direct-mapped entries; a tree met again (crossover often recreates
 * its parents) is not scored again. */
#define GP_MEMO_BITS 14

/* Polls of the cancel callback on the calling thread are this far apart at least: a
 * callback into Python costs microseconds, a candidate tree's score tens of them. */
#define GP_CANCEL_POLL_SECONDS 0.01

/* The one cancel mechanism of a run (runtime/cancel.h): every phase polls
 * gp_cancelled() at least every FREP_CANCEL_POLL_SECONDS of work, on any thread.  flag
 * is raised by a signal handler or another thread; fn (the public API's cancel
 * callback; may be NULL) is called only on the calling thread (thread 0 of every team
 * of the run), at most every GP_CANCEL_POLL_SECONDS, and raises flag when it says
 * stop, so that the worker threads see it too. */
typedef struct gp_cancel {
    volatile sig_atomic_t *flag;   /* never NULL */
    int (*fn)(void *user);
    void *user;
    double next;                   /* frep_now_seconds() of fn's next call */
} gp_cancel;

/* Non-zero once the run is cancelled (k may be NULL: never). */
int gp_cancelled(gp_cancel *k);

typedef struct gp_config {
    uint32_t population;
    int max_depth;          /* 0: gp_default_depth(nprims) */
    double p_subtree;
    uint32_t tournament;
    double p_crossover;
    double p_mutation;
    uint32_t elite;
    uint32_t generations;   /* limit */
    uint32_t stagnation;    /* stop after this many generations without improvement */
    uint64_t seed;
    int threads;            /* <= 0: OpenMP's default */
    double max_time;        /* seconds; <= 0: no limit */
    gp_setops setops;
    /* 1: the progress reports carry how well the best tree explains the scored points
     * (gp_progress.explained; one gp_tree_stats each time the best fitness changes).
     * Only runs with a callback report, so the clique GAs of partition.c never do. */
    int report_explained;
    /* Ctrl-C or the API's cancel callback (gp_cancel below; may be NULL): every GA,
     * the clique GAs included, stops at its next generation (GP_STOP_USER, the best
     * tree kept), the merges and simplifications stop at their next candidate with the
     * tree so far, and evolve_run skips the steps that only improve a tree (growth,
     * polish, support trims, refit). */
    gp_cancel *cancel;
} gp_config;

void gp_config_init(gp_config *c);
int gp_default_depth(uint32_t nprims);

/* What a progress report is about. */
typedef enum gp_phase {
    GP_PHASE_GA,            /* a generation of a GA (the whole run's, or the polish) */
    GP_PHASE_MERGE,         /* two clique trees merged (best_fitness NaN: a partial tree) */
    GP_PHASE_MERGED,        /* the merged, simplified tree on the whole sample */
    GP_PHASE_GROWN,         /* the merged tree after the growth steps (evolve.c) */
    GP_PHASE_CLIQUES,       /* the clique GAs start (generation 0, no tree: fitness NaN) */
    GP_PHASE_SIMPLIFY       /* the final tree's simplification starts (the tree before) */
} gp_phase;

typedef struct gp_progress {
    uint32_t generation;
    double best_fitness;    /* NaN in GP_PHASE_MERGE: a partial tree has none */
    uint32_t best_len;
    double elapsed;         /* seconds since gp_run (part_run) started */
    gp_phase phase;
    /* With gp_config.report_explained (for --trace and --stop-share): the points of
     * the scored set the best tree explains (gp_tree_stats), out of npoints; also in
     * the reports of the merged and grown trees. 0 and 0 otherwise, and in
     * GP_PHASE_MERGE. */
    size_t explained, npoints;
} gp_progress;

/* p->explained and p->npoints for the tree t on c. 0, or -1 (allocation). */
int gp_progress_explained(const gp_cache *c, gp_eval *e, const gp_tree *t, gp_progress *p);

/* Called after each generation; a nonzero return stops the run (Ctrl-C). */
typedef int (*gp_progress_fn)(void *user, const gp_progress *p);

typedef enum gp_stop {
    GP_STOP_GENERATIONS,
    GP_STOP_STAGNATION,
    GP_STOP_TIME,
    GP_STOP_USER
} gp_stop;

typedef struct gp_result {
    gp_tree best;           /* free with tree_free */
    double fitness;
    uint32_t generations;   /* generations run */
    gp_stop stop;
} gp_result;

/* Evolve trees over the cache's primitives. seeds[0..nseeds) join the first
 * population (may be NULL). Returns 0, or -1 on allocation failure or when the cache
 * has no primitive or point. res->best is always initialised (maybe empty). */
int gp_run(const gp_config *cfg, const gp_cache *c, const gp_tree *seeds, uint32_t nseeds,
           gp_progress_fn fn, void *user, gp_result *res);

#endif
