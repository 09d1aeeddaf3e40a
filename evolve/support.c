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

int support_trim(gp_tree *t, gp_setops s, const gp_cache *pc, gp_eval *e,
                 support_grid *g, gp_eval *eg, support_info *info)
{
    memset(info, 0, sizeof *info);
    if (!t->len) return 0;
    gp_opset o = gp_opset_of(s);
    size_t ng = g->c->n, n = pc->n;
    uint32_t k = pc->nprims;
    double *v = frep_malloc((ng ? ng : 1) * sizeof *v), *w = frep_malloc((ng ? ng : 1) * sizeof *w);
    uint8_t *ok = frep_malloc(n ? n : 1), *oks = frep_malloc(n ? n : 1), *pol = NULL;
    edge_list el = { frep_malloc(6 * (ng ? ng : 1) * sizeof *el.ab), 0 };
    gp_tree sub = { NULL, 0, 0 };
    int rc = -1;
    if (!v || !w || !ok || !oks || !el.ab) goto out;
    if (gp_tree_values(g->c, eg, t->code, t->len, v)) goto out;
    size_t u = support_count(g, v);
    info->before = info->after = u;
    for (uint32_t round = 0; round < SUPPORT_MAX_TRIMS && u >= SUPPORT_MIN_GAIN; round++) {
        el.n = 0;
        each_unsupported(g, v, push_edge, &el);
        uint8_t *np = frep_realloc(pol, t->len);
        if (!np) goto out;
        pol = np;
        simplify_polarity(t, s, pol);
        gp_stats st0;
        if (gp_explained(pc, e, t->code, t->len, ok) ||
            gp_tree_stats(pc, e, t->code, t->len, &st0) ||
            gp_tape_record(pc, e, t->code, t->len, NULL) ||
            gp_tape_record(g->c, eg, t->code, t->len, NULL))
            goto out;
        size_t best_u = u, best_in = 0, best_own = 0;
        double best_score = 0;
        uint32_t best_end = 0, best_j = 0;
        int best_neg = -1;
        for (uint32_t un = 0; un < t->len; un++) {
            if (tree_nin(&t->code[un]) != 2 || t->code[un].op != o.uni || !pol[un]) continue;
            uint32_t l0, l1, r0;
            tree_operands(t->code, un, &l0, &l1, &r0);
            const uint32_t ends[2] = { l1, un - 1 };
            for (int side = 0; side < 2; side++) {
                uint32_t end = ends[side], st = tree_subtree_start(t->code, end);
                /* The points S explains alone that the tree explains too: L keeps them. */
                if (gp_explained(pc, e, t->code + st, end - st + 1, oks)) goto out;
                frep_insn lf = gp_tape_leaf(pc, end);
                for (uint32_t j = 0; j < k; j++) {
                    int can[2];
                    cuts(g, &el, j, can);
                    simplify_trim_keeps(t, ends[1 - side], pc, j, ok, oks, can);
                    for (int neg = 0; neg < 2; neg++) {
                        if (!can[neg]) continue;
                        if (simplify_trim_code(&sub, &lf, 1, j, neg, &o)) goto out;
                        gp_stats stt;
                        if (gp_stats_replaced(pc, e, st, end, sub.code, sub.len, &stt)) goto out;
                        /* No point lost; the score may drop by a node's worth (points
                         * at the new face's edge change their nearest primitive). */
                        if (stt.explained < st0.explained || stt.score < st0.score - pc->lambda)
                            continue;
                        if (gp_values_replaced(g->c, eg, st, end, sub.code, sub.len, w)) goto out;
                        /* The fewest unsupported edges; among equals the trim that
                         * removes the least material, of the solid and then of S
                         * itself (a face of the part, not a plane that empties S where
                         * the rest of the solid covers it), then the best score. */
                        size_t uu = support_count(g, w), in = inside(g, w);
                        if (uu > best_u || (uu == best_u && best_neg >= 0 && in < best_in))
                            continue;
                        if (gp_values_taped(g->c, eg, sub.code, sub.len, w)) goto out;
                        size_t own = inside(g, w);
                        if (uu < best_u || best_neg < 0 || in > best_in || own > best_own ||
                            (own == best_own && stt.score > best_score)) {
                            best_u = uu;
                            best_in = in;
                            best_own = own;
                            best_score = stt.score;
                            best_end = end;
                            best_j = j;
                            best_neg = neg;
                        }
                    }
                }
            }
        }
        if (best_neg < 0 || best_u + SUPPORT_MIN_GAIN > u) break;
        uint32_t st = tree_subtree_start(t->code, best_end);
        if (simplify_trim_code(&sub, t->code + st, best_end - st + 1, best_j, best_neg, &o))
            goto out;
        gp_tree keep = { NULL, 0, 0 };
        if (tree_copy(&keep, t) || tree_splice(t, st, best_end, sub.code, sub.len)) {
            tree_free(&keep);
            goto out;
        }
        if (tree_depth(t->code, t->len) > GP_MAX_TREE_DEPTH) {
            int bad = tree_copy(t, &keep);
            tree_free(&keep);
            if (bad) goto out;
            break;
        }
        tree_free(&keep);
        if (simplify_rules(t, s) || gp_tree_values(g->c, eg, t->code, t->len, v)) goto out;
        u = support_count(g, v);
        info->trims++;
    }
    info->after = u;
    rc = 0;
out:
    frep_free(v);
    frep_free(w);
    frep_free(ok);
    frep_free(oks);
    frep_free(pol);
    frep_free(el.ab);
    tree_free(&sub);
    return rc;
}
