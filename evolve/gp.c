/* gp.c - genetic programming over construction trees (Fayolle & Pasko, CAD 2016):
 * generational loop with elitism, tournament selection, crossover and mutation by
 * splicing bytecode (tree.c), fitness by fitness.c in parallel over the population.
 */
#include "config.h"

#include "alloc.h"
#include "gp.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#ifdef _OPENMP
#include <omp.h>
#endif

void gp_config_init(gp_config *c)
{
    memset(c, 0, sizeof *c);
    c->population = GP_DEFAULT_POPULATION;
    c->max_depth = 0;
    c->p_subtree = GP_DEFAULT_P_SUBTREE;
    c->tournament = GP_DEFAULT_TOURNAMENT;
    c->p_crossover = GP_DEFAULT_P_CROSSOVER;
    c->p_mutation = GP_DEFAULT_P_MUTATION;
    c->elite = GP_DEFAULT_ELITE;
    c->generations = GP_DEFAULT_GENERATIONS;
    c->stagnation = GP_DEFAULT_STAGNATION;
    c->seed = 1;
    c->threads = 0;
    c->max_time = 0;
    c->setops = GP_SETOPS_MINMAX;
}

int gp_default_depth(uint32_t nprims)
{
    int d = 1;
    while ((1u << (d - 1)) < nprims && d < 31) d++;  /* leaves of a balanced tree */
    d += GP_DEPTH_SLACK;
    return d > GP_MAX_TREE_DEPTH ? GP_MAX_TREE_DEPTH : d;
}

double gp_now(void)
{
    struct timespec ts;
    timespec_get(&ts, TIME_UTC);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int gp_progress_explained(const gp_cache *c, gp_eval *e, const gp_tree *t, gp_progress *p)
{
    gp_stats st;
    if (gp_tree_stats(c, e, t->code, t->len, &st)) return -1;
    p->explained = st.explained;
    p->npoints = c->n;
    return 0;
}

typedef struct memo_entry {
    uint64_t hash;
    double fitness;
    frep_insn *code;    /* copy of the tree; NULL: empty entry */
    uint32_t len;
} memo_entry;

static memo_entry *memo_find(memo_entry *m, const gp_tree *t, uint64_t h)
{
    memo_entry *e = &m[h & ((1u << GP_MEMO_BITS) - 1)];
    if (e->code && e->hash == h && e->len == t->len &&
        memcmp(e->code, t->code, (size_t)t->len * sizeof *t->code) == 0)
        return e;
    return NULL;
}

static void memo_put(memo_entry *m, const gp_tree *t, uint64_t h, double fit)
{
    memo_entry *e = &m[h & ((1u << GP_MEMO_BITS) - 1)];
    frep_insn *c = frep_realloc(e->code, (size_t)(t->len ? t->len : 1) * sizeof *c);
    if (!c) return;  /* the memo is an optimisation only */
    memcpy(c, t->code, (size_t)t->len * sizeof *c);
    e->code = c;
    e->hash = h;
    e->len = t->len;
    e->fitness = fit;
}

typedef struct indiv {
    gp_tree t;
    double fitness;
    int scored;
} indiv;

/* Better: higher fitness, then shorter, then earlier (a total order for determinism). */
static int better(const indiv *a, uint32_t ia, const indiv *b, uint32_t ib)
{
    if (a->fitness != b->fitness) return a->fitness > b->fitness;
    if (a->t.len != b->t.len) return a->t.len < b->t.len;
    return ia < ib;
}

static uint32_t tournament(const indiv *pop, uint32_t n, uint32_t k, gp_rng *r)
{
    uint32_t best = gp_rng_below(r, n);
    for (uint32_t i = 1; i < k; i++) {
        uint32_t c = gp_rng_below(r, n);
        if (better(&pop[c], c, &pop[best], best)) best = c;
    }
    return best;
}

/* Score every unscored individual: memo lookups serially, the rest in parallel. */
static int score_population(const gp_cache *c, indiv *pop, uint32_t n, memo_entry *memo,
                            gp_eval **ev, int nthreads)
{
    uint32_t *todo = frep_malloc((size_t)n * sizeof *todo);
    uint64_t *hs = frep_malloc((size_t)n * sizeof *hs);
    if (!todo || !hs) {
        frep_free(todo);
        frep_free(hs);
        return -1;
    }
    uint32_t nt = 0;
    for (uint32_t i = 0; i < n; i++) {
        if (pop[i].scored) continue;
        hs[i] = tree_hash(pop[i].t.code, pop[i].t.len);
        memo_entry *e = memo_find(memo, &pop[i].t, hs[i]);
        if (e) {
            pop[i].fitness = e->fitness;
            pop[i].scored = 1;
        } else {
            todo[nt++] = i;
        }
    }
    long ntl = (long)nt;
    int failed = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads)
    for (long k = 0; k < ntl; k++) {
        int tid = 0;
#ifdef _OPENMP
        tid = omp_get_thread_num();
#endif
        indiv *p = &pop[todo[k]];
        double f = -HUGE_VAL;
        if (gp_fitness(c, ev[tid], p->t.code, p->t.len, &f)) {
#pragma omp atomic write
            failed = 1;
        }
        /* NaN data (a primitive NaN at a point): the tree ranks last. */
        if (isnan(f)) f = -HUGE_VAL;
        p->fitness = f;
        p->scored = 1;
    }
    if (failed) {
        frep_free(todo);
        frep_free(hs);
        return -1;
    }
    for (uint32_t k = 0; k < nt; k++) {
        uint32_t i = todo[k];
        /* Two equal new trees in one generation: the second put replaces the first
         * with the same content, so the memo stays deterministic. */
        memo_put(memo, &pop[i].t, hs[i], pop[i].fitness);
    }
    frep_free(todo);
    frep_free(hs);
    return 0;
}

/* Indices of the e best individuals, best first (partial selection; e is small). */
static void best_indices(const indiv *pop, uint32_t n, uint32_t e, uint32_t *out)
{
    for (uint32_t k = 0; k < e; k++) {
        uint32_t b = UINT32_MAX;
        for (uint32_t i = 0; i < n; i++) {
            int taken = 0;
            for (uint32_t q = 0; q < k; q++) taken |= out[q] == i;
            if (taken) continue;
            if (b == UINT32_MAX || better(&pop[i], i, &pop[b], b)) b = i;
        }
        out[k] = b;
    }
}

int gp_run(const gp_config *cfg, const gp_cache *c, const gp_tree *seeds, uint32_t nseeds,
           gp_progress_fn fn, void *user, gp_result *res)
{
    memset(res, 0, sizeof *res);
    res->fitness = -HUGE_VAL;
    if (!c || c->nprims == 0 || c->n == 0) return -1;
    double t0 = gp_now();
    uint32_t P = cfg->population ? cfg->population : 1;
    uint32_t E = cfg->elite < P ? cfg->elite : P;
    uint32_t K = cfg->tournament ? cfg->tournament : 1;
    int D = cfg->max_depth > 0 ? cfg->max_depth : gp_default_depth(c->nprims);
    if (D > GP_MAX_TREE_DEPTH) D = GP_MAX_TREE_DEPTH;
    int nthreads = cfg->threads;
#ifdef _OPENMP
    if (nthreads <= 0) nthreads = omp_get_max_threads();
#else
    nthreads = 1;
#endif
    if (nthreads < 1) nthreads = 1;

    gp_rng rng;
    gp_rng_seed(&rng, cfg->seed);
    indiv *pop = frep_calloc(P, sizeof *pop), *next = frep_calloc(P, sizeof *next);
    memo_entry *memo = frep_calloc((size_t)1 << GP_MEMO_BITS, sizeof *memo);
    gp_eval **ev = frep_calloc((size_t)nthreads, sizeof *ev);
    uint32_t *elite = frep_calloc(E ? E : 1, sizeof *elite);
    int rc = -1;
    if (!pop || !next || !memo || !ev || !elite) goto out;
    for (int i = 0; i < nthreads; i++)
        if (!(ev[i] = gp_eval_new())) goto out;

    for (uint32_t i = 0; i < P; i++) {
        if (i < nseeds && seeds[i].len && tree_depth(seeds[i].code, seeds[i].len) <= GP_MAX_TREE_DEPTH) {
            if (tree_copy(&pop[i].t, &seeds[i])) goto out;
        } else if (tree_grow(&pop[i].t, &rng, cfg->setops, c->nprims, D, cfg->p_subtree)) {
            goto out;
        }
    }

    double best_fit = -HUGE_VAL;
    uint32_t since = 0, gen = 0;
    size_t best_expl = 0;
    res->stop = GP_STOP_GENERATIONS;
    for (gen = 0;; gen++) {
        if (score_population(c, pop, P, memo, ev, nthreads)) goto out;
        best_indices(pop, P, E ? E : 1, elite);
        const indiv *b = &pop[elite[0]];
        if (b->fitness > best_fit) {
            best_fit = b->fitness;
            since = 0;
            gp_stats st;
            if (fn && cfg->report_explained) {
                if (gp_tree_stats(c, ev[0], b->t.code, b->t.len, &st)) goto out;
                best_expl = st.explained;
            }
        } else {
            since++;
        }
        if (tree_copy(&res->best, &b->t)) goto out;
        res->fitness = b->fitness;
        res->generations = gen + 1;
        double el = gp_now() - t0;
        if (fn) {
            gp_progress pr = { gen + 1, b->fitness, b->t.len, el, GP_PHASE_GA, 0, 0 };
            if (cfg->report_explained) {
                pr.explained = best_expl;
                pr.npoints = c->n;
            }
            if (fn(user, &pr)) { res->stop = GP_STOP_USER; break; }
        }
        if (gen + 1 >= cfg->generations) { res->stop = GP_STOP_GENERATIONS; break; }
        if (cfg->stagnation && since >= cfg->stagnation) { res->stop = GP_STOP_STAGNATION; break; }
        if (cfg->max_time > 0 && el >= cfg->max_time) { res->stop = GP_STOP_TIME; break; }

        /* Next generation. */
        for (uint32_t k = 0; k < E; k++) {
            if (tree_copy(&next[k].t, &pop[elite[k]].t)) goto out;
            next[k].fitness = pop[elite[k]].fitness;
            next[k].scored = 1;
        }
        for (uint32_t i = E; i < P; i++) {
            uint32_t p1 = tournament(pop, P, K, &rng);
            double u = gp_rng_unif(&rng);
            indiv *ch = &next[i];
            ch->scored = 0;
            if (u < cfg->p_crossover) {
                uint32_t p2 = tournament(pop, P, K, &rng);
                int r = tree_crossover(&ch->t, &pop[p1].t, &pop[p2].t, &rng, D);
                if (r < 0) goto out;
                if (r == 0) {  /* cancelled: the child is its parent, fitness known */
                    ch->fitness = pop[p1].fitness;
                    ch->scored = 1;
                }
            } else if (u < cfg->p_crossover + cfg->p_mutation) {
                if (tree_copy(&ch->t, &pop[p1].t) ||
                    tree_mutate(&ch->t, &rng, cfg->setops, c->nprims, D, cfg->p_subtree))
                    goto out;
            } else {
                if (tree_copy(&ch->t, &pop[p1].t)) goto out;
                ch->fitness = pop[p1].fitness;
                ch->scored = 1;
            }
        }
        indiv *tmp = pop;
        pop = next;
        next = tmp;
    }
    rc = 0;
out:
    if (pop)
        for (uint32_t i = 0; i < P; i++) tree_free(&pop[i].t);
    if (next)
        for (uint32_t i = 0; i < P; i++) tree_free(&next[i].t);
    if (memo)
        for (size_t i = 0; i < ((size_t)1 << GP_MEMO_BITS); i++) frep_free(memo[i].code);
    if (ev)
        for (int i = 0; i < nthreads; i++) gp_eval_free(ev[i]);
    frep_free(pop);
    frep_free(next);
    frep_free(memo);
    frep_free(ev);
    frep_free(elite);
    return rc;
}
