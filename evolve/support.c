/* support.c - trims of material that no point supports (support.h; doc/evolve.md,
 * "Support").
 *
 * The grid's values of a tree come from its own cache (the primitives evaluated at
 * the nodes once), scored like the points: a trim is one replaced subtree, so both
 * the sample's statistics and the grid's values of a candidate come from the tapes of
 * the tree (fitness.h), in the two evaluators.
 */
#include "config.h"

#include "alloc.h"
#include "support.h"

#include "simplify.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The field at node a, clipped. */
static double clipped(const support_grid *g, const double *v, size_t a)
{
    return v[a] < g->clip[a] ? v[a] : g->clip[a];
}

/* 1 when node (i, j, k) = a is farther than tau from every point. */
static int far_node(support_grid *g, size_t a, size_t i, size_t j, size_t k)
{
    if (isnan(g->dist[a])) {
        double p[3], d2;
        uint32_t nb;
        for (int c = 0; c < 3; c++)
            p[c] = g->o[c] + (double)i * g->u[0][c] + (double)j * g->u[1][c] +
                   (double)k * g->u[2][c];
        g->dist[a] = kd_knn(g->cloud, p, 1, &nb, &d2) ? sqrt(d2) : HUGE_VAL;
    }
    return g->dist[a] > g->tau;
}

/* Calls fn(user, a, b) for every unsupported edge (a, b) of v; returns their number. */
static size_t each_unsupported(support_grid *g, const double *v,
                               void (*fn)(void *, size_t, size_t), void *user)
{
    const size_t d0 = g->dims[0], d1 = g->dims[1], d2 = g->dims[2];
    const size_t step[3] = { d1 * d2, d2, 1 };
    size_t count = 0;
    for (size_t i = 0; i < d0; i++)
        for (size_t j = 0; j < d1; j++)
            for (size_t k = 0; k < d2; k++) {
                size_t a = (i * d1 + j) * d2 + k;
                const int more[3] = { i + 1 < d0, j + 1 < d1, k + 1 < d2 };
                const size_t nb[3][3] = { { i + 1, j, k }, { i, j + 1, k }, { i, j, k + 1 } };
                int ina = clipped(g, v, a) >= 0;
                for (int d = 0; d < 3; d++) {
                    if (!more[d]) continue;
                    size_t b = a + step[d];
                    if ((clipped(g, v, b) >= 0) == ina) continue;
                    if (!far_node(g, a, i, j, k) || !far_node(g, b, nb[d][0], nb[d][1], nb[d][2]))
                        continue;
                    count++;
                    if (fn) fn(user, a, b);
                }
            }
    return count;
}

size_t support_count(support_grid *g, const double *v)
{
    return each_unsupported(g, v, NULL, NULL);
}

/* Nodes inside the clipped solid. */
static size_t inside(const support_grid *g, const double *v)
{
    size_t n = 0;
    for (size_t a = 0; a < g->c->n; a++) n += clipped(g, v, a) >= 0;
    return n;
}

/* The unsupported edges of the current tree, as node pairs. */
typedef struct edge_list {
    size_t *ab;
    size_t n;
} edge_list;

static void push_edge(void *user, size_t a, size_t b)
{
    edge_list *l = user;
    l->ab[2 * l->n] = a;
    l->ab[2 * l->n + 1] = b;
    l->n++;
}

/* cut[ng]: L = p (ng 0) or ~p (ng 1) is outside the solid at an end of some unsupported
 * edge, so S & L removes material there (a trim elsewhere cannot help). */
static void cuts(const support_grid *g, const edge_list *l, uint32_t j, int cut[2])
{
    const double *v = g->c->v + (size_t)j * g->c->n;
    cut[0] = cut[1] = 0;
    for (size_t q = 0; q < 2 * l->n && !(cut[0] && cut[1]); q++) {
        double x = v[l->ab[q]];
        if (x < 0) cut[0] = 1;
        if (x > 0) cut[1] = 1;
    }
}

/* One support_trim: the grid's values of the tree (v) and of a variant (w), the
 * points the tree explains, and the best trim of the round. */
typedef struct trim_state {
    gp_tree *t;
    gp_setops s;
    gp_opset o;
    const gp_cache *pc;      /* the scored sample */
    gp_eval *e;
    support_grid *g;
    gp_eval *eg;             /* evaluator on the grid */
    double *v, *w;           /* per node: the tree's value; a variant's */
    uint8_t *ok, *oks;       /* per point: the tree explains it; the operand S does */
    uint8_t *pol;            /* per node of t: adds material (simplify_polarity) */
    edge_list el;            /* the tree's unsupported edges */
    gp_tree sub;             /* scratch: a trim's replacement */
    gp_stats st0;            /* the tree's statistics on the sample */
    size_t u;                /* its unsupported edges */
    size_t best_u, best_in, best_own;
    double best_score;
    uint32_t best_end, best_j;
    int best_neg;            /* -1: no candidate yet */
} trim_state;

/* The round's view of the tree: its unsupported edges, polarity, explained points and
 * statistics, and its tapes on the sample and on the grid. */
static int trim_round_start(trim_state *ts)
{
    gp_tree *t = ts->t;
    ts->el.n = 0;
    each_unsupported(ts->g, ts->v, push_edge, &ts->el);
    uint8_t *np = frep_realloc(ts->pol, t->len);
    if (!np) return -1;
    ts->pol = np;
    simplify_polarity(t, ts->s, ts->pol);
    if (gp_explained(ts->pc, ts->e, t->code, t->len, ts->ok) ||
        gp_tree_stats(ts->pc, ts->e, t->code, t->len, &ts->st0) ||
        gp_tape_record(ts->pc, ts->e, t->code, t->len, NULL) ||
        gp_tape_record(ts->g->c, ts->eg, t->code, t->len, NULL))
        return -1;
    ts->best_u = ts->u;
    ts->best_in = ts->best_own = 0;
    ts->best_score = 0;
    ts->best_end = ts->best_j = 0;
    ts->best_neg = -1;
    return 0;
}

/* The trim S & L (S the subtree [st, end], L = p_j or ~p_j), kept as the best when no
 * point is lost (the score may drop by a node's worth: points at the new face's edge
 * change their nearest primitive) and it leaves the fewest unsupported edges; among
 * equals the trim that removes the least material, of the solid and then of S itself
 * (a face of the part, not a plane that empties S where the rest of the solid covers
 * it), then the best score. */
static int trim_candidate(trim_state *ts, uint32_t st, uint32_t end, const frep_insn *lf,
                          uint32_t j, int neg)
{
    const gp_cache *pc = ts->pc;
    support_grid *g = ts->g;
    if (simplify_trim_code(&ts->sub, lf, 1, j, neg, &ts->o)) return -1;
    gp_stats stt;
    if (gp_stats_replaced(pc, ts->e, st, end, ts->sub.code, ts->sub.len, &stt)) return -1;
    if (stt.explained < ts->st0.explained || stt.score < ts->st0.score - pc->lambda) return 0;
    if (gp_values_replaced(g->c, ts->eg, st, end, ts->sub.code, ts->sub.len, ts->w)) return -1;
    size_t uu = support_count(g, ts->w), in = inside(g, ts->w);
    if (uu > ts->best_u || (uu == ts->best_u && ts->best_neg >= 0 && in < ts->best_in)) return 0;
    if (gp_values_taped(g->c, ts->eg, ts->sub.code, ts->sub.len, ts->w)) return -1;
    size_t own = inside(g, ts->w);
    if (uu < ts->best_u || ts->best_neg < 0 || in > ts->best_in || own > ts->best_own ||
        (own == ts->best_own && stt.score > ts->best_score)) {
        ts->best_u = uu;
        ts->best_in = in;
        ts->best_own = own;
        ts->best_score = stt.score;
        ts->best_end = end;
        ts->best_j = j;
        ts->best_neg = neg;
    }
    return 0;
}

/* Every trim of the operand ending at `end` of the union whose other operand ends at
 * `other`: the literals that keep the points S explains alone (and the tree too) and
 * cut material at an unsupported edge. */
static int trim_operand(trim_state *ts, uint32_t end, uint32_t other)
{
    const gp_tree *t = ts->t;
    uint32_t st = tree_subtree_start(t->code, end);
    if (gp_explained(ts->pc, ts->e, t->code + st, end - st + 1, ts->oks)) return -1;
    frep_insn lf = gp_tape_leaf(ts->pc, end);
    for (uint32_t j = 0; j < ts->pc->nprims; j++) {
        int can[2];
        cuts(ts->g, &ts->el, j, can);
        simplify_trim_keeps(t, other, ts->pc, j, ts->ok, ts->oks, can);
        for (int neg = 0; neg < 2; neg++)
            if (can[neg] && trim_candidate(ts, st, end, &lf, j, neg)) return -1;
    }
    return 0;
}

/* The best trim of the round over both operands of every union that adds material. */
static int trim_search(trim_state *ts)
{
    const gp_tree *t = ts->t;
    for (uint32_t un = 0; un < t->len; un++) {
        if (tree_nin(&t->code[un]) != 2 || t->code[un].op != ts->o.uni || !ts->pol[un]) continue;
        uint32_t l0, l1, r0;
        tree_operands(t->code, un, &l0, &l1, &r0);
        if (trim_operand(ts, l1, un - 1) || trim_operand(ts, un - 1, l1)) return -1;
    }
    return 0;
}

/* The best trim applied (the exact rules after it) and the unsupported edges counted
 * again. 1: not applied, since the tree would grow too deep. */
static int trim_apply(trim_state *ts, support_info *info)
{
    gp_tree *t = ts->t;
    uint32_t st = tree_subtree_start(t->code, ts->best_end);
    if (simplify_trim_code(&ts->sub, t->code + st, ts->best_end - st + 1, ts->best_j,
                           ts->best_neg, &ts->o))
        return -1;
    gp_tree keep = { NULL, 0, 0 };
    if (tree_copy(&keep, t) || tree_splice(t, st, ts->best_end, ts->sub.code, ts->sub.len)) {
        tree_free(&keep);
        return -1;
    }
    if (tree_depth(t->code, t->len) > GP_MAX_TREE_DEPTH) {
        int bad = tree_copy(t, &keep);
        tree_free(&keep);
        return bad ? -1 : 1;
    }
    tree_free(&keep);
    if (simplify_rules(t, ts->s) || gp_tree_values(ts->g->c, ts->eg, t->code, t->len, ts->v))
        return -1;
    ts->u = support_count(ts->g, ts->v);
    info->trims++;
    return 0;
}

/* Rounds of trims while the best removes at least SUPPORT_MIN_GAIN unsupported edges. */
static int trim_rounds(trim_state *ts, support_info *info)
{
    if (gp_tree_values(ts->g->c, ts->eg, ts->t->code, ts->t->len, ts->v)) return -1;
    ts->u = support_count(ts->g, ts->v);
    info->before = info->after = ts->u;
    for (uint32_t round = 0; round < SUPPORT_MAX_TRIMS && ts->u >= SUPPORT_MIN_GAIN; round++) {
        if (trim_round_start(ts) || trim_search(ts)) return -1;
        if (ts->best_neg < 0 || ts->best_u + SUPPORT_MIN_GAIN > ts->u) break;
        int r = trim_apply(ts, info);
        if (r < 0) return -1;
        if (r > 0) break;
    }
    info->after = ts->u;
    return 0;
}

int support_trim(gp_tree *t, gp_setops s, const gp_cache *pc, gp_eval *e,
                 support_grid *g, gp_eval *eg, support_info *info)
{
    memset(info, 0, sizeof *info);
    if (!t->len) return 0;
    size_t ng = g->c->n, n = pc->n;
    trim_state ts;
    memset(&ts, 0, sizeof ts);
    ts.t = t;
    ts.s = s;
    ts.o = gp_opset_of(s);
    ts.pc = pc;
    ts.e = e;
    ts.g = g;
    ts.eg = eg;
    ts.v = frep_malloc((ng ? ng : 1) * sizeof *ts.v);
    ts.w = frep_malloc((ng ? ng : 1) * sizeof *ts.w);
    ts.ok = frep_malloc(n ? n : 1);
    ts.oks = frep_malloc(n ? n : 1);
    ts.el.ab = frep_malloc(6 * (ng ? ng : 1) * sizeof *ts.el.ab);
    int rc = !ts.v || !ts.w || !ts.ok || !ts.oks || !ts.el.ab ? -1 : trim_rounds(&ts, info);
    frep_free(ts.v);
    frep_free(ts.w);
    frep_free(ts.ok);
    frep_free(ts.oks);
    frep_free(ts.pol);
    frep_free(ts.el.ab);
    tree_free(&ts.sub);
    return rc;
}
