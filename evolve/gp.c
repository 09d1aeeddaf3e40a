/* gp.c - genetic programming over construction trees (Fayolle & Pasko, CAD 2016):
 * generational loop with elitism, tournament selection, crossover and mutation by
 * splicing bytecode (tree.c), fitness by fitness.c in parallel over the population.
 */
#include "config.h"

#include "alloc.h"
#include "gp.h"
#include "threads.h"
#include "util.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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

/* The calling thread of the run: thread 0 of every enclosing team (the thread that
 * starts a parallel region becomes thread 0 of its team). */
static int gp_on_calling_thread(void)
{
#ifdef _OPENMP
    for (int l = omp_get_level(); l > 0; l--)
        if (omp_get_ancestor_thread_num(l) != 0) return 0;
#endif
    return 1;
}

int gp_cancelled(gp_cancel *k)
{
    if (!k) return 0;
    if (*k->flag) return 1;
    if (k->fn && gp_on_calling_thread()) {
        double t = frep_now_seconds();
        if (t >= k->next) {
            k->next = t + GP_CANCEL_POLL_SECONDS;
            if (k->fn(k->user)) *k->flag = 1;
        }
    }
    return *k->flag != 0;
}

int gp_default_depth(uint32_t nprims)
{
    int d = 1;
    while ((1u << (d - 1)) < nprims && d < 31) d++;  /* leaves of a balanced tree */
    d += GP_DEPTH_SLACK;
    return d > GP_MAX_TREE_DEPTH ? GP_MAX_TREE_DEPTH : d;
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
        int tid = frep_thread_num();
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


/* One gp_run: the limits, the two generations, the memo and the evaluators. */
typedef struct gp_state {
    const gp_config *cfg;
    const gp_cache *c;
    gp_progress_fn fn;
    void *user;
    gp_result *res;
    double t0;               /* frep_now_seconds() at the start */
    uint32_t P, E, K;        /* population, elite, tournament size */
    int D;                   /* maximum depth */
    int nthreads;
    gp_rng rng;              /* every random choice, made serially */
    indiv *pop, *next;       /* this generation and the one being bred */
    memo_entry *memo;
    gp_eval **ev;            /* one per thread */
    uint32_t *elite;         /* indices of the E best of pop, best first */
    double best_fit;         /* the best fitness so far */
    uint32_t since;          /* generations without improvement */
    size_t best_expl;        /* points the best tree explains (report_explained) */
} gp_state;

/* The limits from the config, the arrays, one evaluator per thread. */
static int gp_setup(gp_state *s)
{
    const gp_config *cfg = s->cfg;
    s->P = cfg->population ? cfg->population : 1;
    s->E = cfg->elite < s->P ? cfg->elite : s->P;
    s->K = cfg->tournament ? cfg->tournament : 1;
    s->D = cfg->max_depth > 0 ? cfg->max_depth : gp_default_depth(s->c->nprims);
    if (s->D > GP_MAX_TREE_DEPTH) s->D = GP_MAX_TREE_DEPTH;
    s->nthreads = frep_threads(cfg->threads);
    gp_rng_seed(&s->rng, cfg->seed);
    s->pop = frep_calloc(s->P, sizeof *s->pop);
    s->next = frep_calloc(s->P, sizeof *s->next);
    s->memo = frep_calloc((size_t)1 << GP_MEMO_BITS, sizeof *s->memo);
    s->ev = frep_calloc((size_t)s->nthreads, sizeof *s->ev);
    s->elite = frep_calloc(s->E ? s->E : 1, sizeof *s->elite);
    if (!s->pop || !s->next || !s->memo || !s->ev || !s->elite) return -1;
    for (int i = 0; i < s->nthreads; i++)
        if (!(s->ev[i] = gp_eval_new())) return -1;
    return 0;
}

/* The first population: the seeds that fit the depth limit, then random trees. */
static int gp_first_population(gp_state *s, const gp_tree *seeds, uint32_t nseeds)
{
    const gp_config *cfg = s->cfg;
    for (uint32_t i = 0; i < s->P; i++) {
        if (i < nseeds && seeds[i].len &&
            tree_depth(seeds[i].code, seeds[i].len) <= GP_MAX_TREE_DEPTH) {
            if (tree_copy(&s->pop[i].t, &seeds[i])) return -1;
        } else if (tree_grow(&s->pop[i].t, &s->rng, cfg->setops, s->c->nprims, s->D,
                             cfg->p_subtree)) {
            return -1;
        }
    }
    return 0;
}

/* The elite of the scored generation; the best tree so far into res. */
static int gp_track_best(gp_state *s, uint32_t gen)
{
    best_indices(s->pop, s->P, s->E ? s->E : 1, s->elite);
    const indiv *b = &s->pop[s->elite[0]];
    if (b->fitness > s->best_fit) {
        s->best_fit = b->fitness;
        s->since = 0;
        gp_stats st;
        if (s->fn && s->cfg->report_explained) {
            if (gp_tree_stats(s->c, s->ev[0], b->t.code, b->t.len, &st)) return -1;
            s->best_expl = st.explained;
        }
    } else {
        s->since++;
    }
    if (tree_copy(&s->res->best, &b->t)) return -1;
    s->res->fitness = b->fitness;
    s->res->generations = gen + 1;
    return 0;
}

/* The progress report and the stopping rules, in this order; 1: stop (res->stop set). */
static int gp_stop_now(gp_state *s, uint32_t gen)
{
    const gp_config *cfg = s->cfg;
    const indiv *b = &s->pop[s->elite[0]];
    double el = frep_now_seconds() - s->t0;
    if (s->fn) {
        gp_progress pr = { gen + 1, b->fitness, b->t.len, el, GP_PHASE_GA, 0, 0 };
        if (cfg->report_explained) {
            pr.explained = s->best_expl;
            pr.npoints = s->c->n;
        }
        if (s->fn(s->user, &pr)) { s->res->stop = GP_STOP_USER; return 1; }
    }
    if (gp_cancelled(cfg->cancel)) { s->res->stop = GP_STOP_USER; return 1; }
    if (gen + 1 >= cfg->generations) { s->res->stop = GP_STOP_GENERATIONS; return 1; }
    if (cfg->stagnation && s->since >= cfg->stagnation) { s->res->stop = GP_STOP_STAGNATION; return 1; }
    if (cfg->max_time > 0 && el >= cfg->max_time) { s->res->stop = GP_STOP_TIME; return 1; }
    return 0;
}

/* Child i of the next generation: crossover, mutation or reproduction of tournament
 * winners (a cancelled crossover and a reproduction keep the parent's fitness). */
static int gp_breed_one(gp_state *s, uint32_t i)
{
    const gp_config *cfg = s->cfg;
    indiv *pop = s->pop;
    uint32_t p1 = tournament(pop, s->P, s->K, &s->rng);
    double u = gp_rng_unif(&s->rng);
    indiv *ch = &s->next[i];
    ch->scored = 0;
    if (u < cfg->p_crossover) {
        uint32_t p2 = tournament(pop, s->P, s->K, &s->rng);
        int r = tree_crossover(&ch->t, &pop[p1].t, &pop[p2].t, &s->rng, s->D);
        if (r < 0) return -1;
        if (r == 0) {  /* cancelled: the child is its parent, fitness known */
            ch->fitness = pop[p1].fitness;
            ch->scored = 1;
        }
    } else if (u < cfg->p_crossover + cfg->p_mutation) {
        if (tree_copy(&ch->t, &pop[p1].t) ||
            tree_mutate(&ch->t, &s->rng, cfg->setops, s->c->nprims, s->D, cfg->p_subtree))
            return -1;
    } else {
        if (tree_copy(&ch->t, &pop[p1].t)) return -1;
        ch->fitness = pop[p1].fitness;
        ch->scored = 1;
    }
    return 0;
}

/* The next generation: the elite copied, the rest bred; it becomes pop. */
static int gp_next_generation(gp_state *s)
{
    for (uint32_t k = 0; k < s->E; k++) {
        if (tree_copy(&s->next[k].t, &s->pop[s->elite[k]].t)) return -1;
        s->next[k].fitness = s->pop[s->elite[k]].fitness;
        s->next[k].scored = 1;
    }
    for (uint32_t i = s->E; i < s->P; i++)
        if (gp_breed_one(s, i)) return -1;
    indiv *tmp = s->pop;
    s->pop = s->next;
    s->next = tmp;
    return 0;
}

static void gp_state_free(gp_state *s)
{
    if (s->pop)
        for (uint32_t i = 0; i < s->P; i++) tree_free(&s->pop[i].t);
    if (s->next)
        for (uint32_t i = 0; i < s->P; i++) tree_free(&s->next[i].t);
    if (s->memo)
        for (size_t i = 0; i < ((size_t)1 << GP_MEMO_BITS); i++) frep_free(s->memo[i].code);
    if (s->ev)
        for (int i = 0; i < s->nthreads; i++) gp_eval_free(s->ev[i]);
    frep_free(s->pop);
    frep_free(s->next);
    frep_free(s->memo);
    frep_free(s->ev);
    frep_free(s->elite);
}

int gp_run(const gp_config *cfg, const gp_cache *c, const gp_tree *seeds, uint32_t nseeds,
           gp_progress_fn fn, void *user, gp_result *res)
{
    memset(res, 0, sizeof *res);
    res->fitness = -HUGE_VAL;
    if (!c || c->nprims == 0 || c->n == 0) return -1;
    gp_state s;
    memset(&s, 0, sizeof s);
    s.cfg = cfg;
    s.c = c;
    s.fn = fn;
    s.user = user;
    s.res = res;
    s.t0 = frep_now_seconds();
    s.best_fit = -HUGE_VAL;
    int rc = -1;
    if (gp_setup(&s) || gp_first_population(&s, seeds, nseeds)) goto out;
    res->stop = GP_STOP_GENERATIONS;
    /* The generational loop: score, keep the best, report and stop, breed. */
    for (uint32_t gen = 0;; gen++) {
        if (score_population(c, s.pop, s.P, s.memo, s.ev, s.nthreads) ||
            gp_track_best(&s, gen))
            goto out;
        if (gp_stop_now(&s, gen)) break;
        if (gp_next_generation(&s)) goto out;
    }
    rc = 0;
out:
    gp_state_free(&s);
    return rc;
}
