/* partition.c - overlap graph, maximal cliques, per-clique GAs and the merge of their
 * trees (Friedrich, Feld, Phan, Fayolle, WSCG 2018); called by evolve.c before (or
 * instead of) the GA over all primitives.
 */
#define _POSIX_C_SOURCE 200809L /* nanosleep */

#include "config.h"

#include "alloc.h"
#include "linalg.h"
#include "partition.h"
#include "simplify.h"
#include "threads.h"
#include "util.h"
#include "vec3.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* ---- oriented boxes ----------------------------------------------------------- */

/* Box axes: the covariance's eigenvectors, iterated to full convergence whatever the
 * points' scale (off-diagonal sum below 1e-300); 50 sweeps bound the loop. */
static const linalg_jacobi_stop obb_stop = {50, 1e-300, 0, 1e-300};

void part_obb_of_points(const double *x, const double *y, const double *z,
                        const size_t *idx, size_t m, gp_obb *b)
{
    memset(b, 0, sizeof *b);
    if (m == 0) return;
    double mean[3] = { 0, 0, 0 };
    for (size_t k = 0; k < m; k++) {
        size_t i = idx ? idx[k] : k;
        mean[0] += x[i];
        mean[1] += y[i];
        mean[2] += z[i];
    }
    for (int q = 0; q < 3; q++) mean[q] /= (double)m;
    double cov[3][3] = { { 0 } };
    for (size_t k = 0; k < m; k++) {
        size_t i = idx ? idx[k] : k;
        double d[3] = { x[i] - mean[0], y[i] - mean[1], z[i] - mean[2] };
        for (int r = 0; r < 3; r++)
            for (int s = 0; s < 3; s++) cov[r][s] += d[r] * d[s];
    }
    double v[3][3], w[3];
    linalg_sym3_jacobi((const double(*)[3])cov, &obb_stop, w, v);
    for (int a = 0; a < 3; a++)
        for (int q = 0; q < 3; q++) b->ax[a][q] = v[q][a];
    double lo[3] = { HUGE_VAL, HUGE_VAL, HUGE_VAL }, hi[3] = { -HUGE_VAL, -HUGE_VAL, -HUGE_VAL };
    for (size_t k = 0; k < m; k++) {
        size_t i = idx ? idx[k] : k;
        double d[3] = { x[i] - mean[0], y[i] - mean[1], z[i] - mean[2] };
        for (int a = 0; a < 3; a++) {
            double t = d[0] * b->ax[a][0] + d[1] * b->ax[a][1] + d[2] * b->ax[a][2];
            if (t < lo[a]) lo[a] = t;
            if (t > hi[a]) hi[a] = t;
        }
    }
    for (int q = 0; q < 3; q++) b->c[q] = mean[q];
    for (int a = 0; a < 3; a++) {
        double mid = 0.5 * (lo[a] + hi[a]);
        for (int q = 0; q < 3; q++) b->c[q] += mid * b->ax[a][q];
        b->h[a] = 0.5 * (hi[a] - lo[a]);
    }
    b->valid = 1;
}

int part_obb_overlap(const gp_obb *a, const gp_obb *b, double margin)
{
    if (!a->valid || !b->valid) return 1;
    double d[3] = { b->c[0] - a->c[0], b->c[1] - a->c[1], b->c[2] - a->c[2] };
    double axes[15][3];
    int na = 0;
    for (int k = 0; k < 3; k++) {
        memcpy(axes[na++], a->ax[k], sizeof axes[0]);
        memcpy(axes[na++], b->ax[k], sizeof axes[0]);
    }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            const double *u = a->ax[i], *w = b->ax[j];
            double c[3] = { u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                            u[0] * w[1] - u[1] * w[0] };
            /* Parallel axes give no new separating direction. */
            if (vec3_dot(c, c) < 1e-12) continue;
            memcpy(axes[na++], c, sizeof c);
        }
    for (int k = 0; k < na; k++) {
        const double *L = axes[k];
        double ra = 0, rb = 0;
        for (int q = 0; q < 3; q++) {
            ra += (a->h[q] + margin) * fabs(vec3_dot(a->ax[q], L));
            rb += (b->h[q] + margin) * fabs(vec3_dot(b->ax[q], L));
        }
        if (fabs(vec3_dot(d, L)) > ra + rb) return 0;
    }
    return 1;
}

int part_obb_contains(const gp_obb *b, const double p[3], double margin)
{
    if (!b->valid) return 0;
    double d[3] = { p[0] - b->c[0], p[1] - b->c[1], p[2] - b->c[2] };
    for (int a = 0; a < 3; a++)
        if (fabs(vec3_dot(d, b->ax[a])) > b->h[a] + margin) return 0;
    return 1;
}

/* ---- overlap graph -------------------------------------------------------------- */

int part_graph_has(const gp_graph *g, uint32_t i, uint32_t j)
{
    return (int)((g->adj[(size_t)i * g->words + j / 64] >> (j % 64)) & 1u);
}

void part_graph_set(gp_graph *g, uint32_t i, uint32_t j)
{
    g->adj[(size_t)i * g->words + j / 64] |= (uint64_t)1 << (j % 64);
    g->adj[(size_t)j * g->words + i / 64] |= (uint64_t)1 << (i % 64);
}

void part_graph_free(gp_graph *g)
{
    frep_free(g->adj);
    memset(g, 0, sizeof *g);
}

typedef struct sweep_item {
    double lo[3], hi[3];
    uint32_t i;
} sweep_item;

static int cmp_sweep(const void *a, const void *b)
{
    const sweep_item *p = a, *q = b;
    if (p->lo[0] != q->lo[0]) return p->lo[0] < q->lo[0] ? -1 : 1;
    return p->i < q->i ? -1 : p->i > q->i;
}

int part_overlap_graph(const gp_obb *boxes, uint32_t n, double margin, gp_graph *g)
{
    memset(g, 0, sizeof *g);
    if (n > PART_MAX_PRIMS) return -1;
    g->n = n;
    g->words = (n + 63) / 64;
    g->adj = frep_calloc((size_t)n * (g->words ? g->words : 1), sizeof *g->adj);
    sweep_item *it = frep_malloc((size_t)(n ? n : 1) * sizeof *it);
    if (!g->adj || !it) {
        frep_free(it);
        part_graph_free(g);
        return -1;
    }
    uint32_t nv = 0;
    for (uint32_t i = 0; i < n; i++) {
        const gp_obb *b = &boxes[i];
        if (!b->valid) {  /* no proxy: conservatively overlaps everything */
            for (uint32_t j = 0; j < n; j++)
                if (j != i) part_graph_set(g, i, j);
            continue;
        }
        sweep_item *s = &it[nv++];
        s->i = i;
        for (int q = 0; q < 3; q++) {
            double r = 0;
            for (int a = 0; a < 3; a++) r += (b->h[a] + margin) * fabs(b->ax[a][q]);
            s->lo[q] = b->c[q] - r;
            s->hi[q] = b->c[q] + r;
        }
    }
    qsort(it, nv, sizeof *it, cmp_sweep);
    for (uint32_t a = 0; a < nv; a++)
        for (uint32_t b = a + 1; b < nv && it[b].lo[0] <= it[a].hi[0]; b++) {
            if (it[b].lo[1] > it[a].hi[1] || it[a].lo[1] > it[b].hi[1] ||
                it[b].lo[2] > it[a].hi[2] || it[a].lo[2] > it[b].hi[2])
                continue;
            if (part_obb_overlap(&boxes[it[a].i], &boxes[it[b].i], margin))
                part_graph_set(g, it[a].i, it[b].i);
        }
    frep_free(it);
    return 0;
}

/* ---- maximal cliques -------------------------------------------------------------- */

typedef struct bk_state {
    const gp_graph *g;
    uint32_t *r;          /* current clique */
    uint32_t nr;
    uint32_t max;
    uint32_t count, cap_members, n_members;
    uint32_t *start, *members;
    size_t cap_start;
    int overflow, nomem;
} bk_state;

static int bk_report(bk_state *s)
{
    if (s->count >= s->max) {
        s->overflow = 1;
        return -1;
    }
    if (s->n_members + s->nr > s->cap_members) {
        uint32_t nc = s->cap_members ? s->cap_members * 2 : 64;
        while (nc < s->n_members + s->nr) nc *= 2;
        uint32_t *m = frep_realloc(s->members, (size_t)nc * sizeof *m);
        if (!m) { s->nomem = 1; return -1; }
        s->members = m;
        s->cap_members = nc;
    }
    if ((size_t)s->count + 2 > s->cap_start) {
        size_t nc = s->cap_start ? s->cap_start * 2 : 64;
        uint32_t *st = frep_realloc(s->start, nc * sizeof *st);
        if (!st) { s->nomem = 1; return -1; }
        s->start = st;
        s->cap_start = nc;
    }
    /* Members ascending: insertion sort of the (small) clique. */
    uint32_t base = s->n_members;
    for (uint32_t k = 0; k < s->nr; k++) {
        uint32_t v = s->r[k], p = base + k;
        while (p > base && s->members[p - 1] > v) {
            s->members[p] = s->members[p - 1];
            p--;
        }
        s->members[p] = v;
    }
    s->n_members += s->nr;
    s->start[s->count] = base;
    s->count++;
    s->start[s->count] = s->n_members;
    return 0;
}

static uint32_t popcount64(uint64_t x)
{
    uint32_t c = 0;
    while (x) { x &= x - 1; c++; }
    return c;
}

/* BronKerbosch2 with the pivot maximising |P & N(u)| (Tomita et al.). p and x are
 * owned by the caller; recursion depth is at most the largest clique. */
static int bk(bk_state *s, uint64_t *p, uint64_t *x)
{
    const gp_graph *g = s->g;
    uint32_t W = g->words;
    int emptyp = 1, emptyx = 1;
    for (uint32_t w = 0; w < W; w++) {
        if (p[w]) emptyp = 0;
        if (x[w]) emptyx = 0;
    }
    if (emptyp) return emptyx ? bk_report(s) : 0;
    uint32_t pivot = 0, best = 0;
    int have = 0;
    for (uint32_t w = 0; w < W; w++) {
        uint64_t px = p[w] | x[w];
        while (px) {
            uint32_t u = w * 64 + (uint32_t)__builtin_ctzll(px);
            px &= px - 1;
            const uint64_t *nu = g->adj + (size_t)u * W;
            uint32_t c = 0;
            for (uint32_t q = 0; q < W; q++) c += popcount64(p[q] & nu[q]);
            if (!have || c > best) { pivot = u; best = c; have = 1; }
        }
    }
    uint64_t *np = frep_malloc((size_t)2 * W * sizeof *np);
    if (!np) { s->nomem = 1; return -1; }
    uint64_t *nx = np + W;
    const uint64_t *npiv = g->adj + (size_t)pivot * W;
    for (uint32_t w = 0; w < W; w++) {
        uint64_t cand = p[w] & ~npiv[w];
        while (cand) {
            uint32_t v = w * 64 + (uint32_t)__builtin_ctzll(cand);
            cand &= cand - 1;
            const uint64_t *nv = g->adj + (size_t)v * W;
            for (uint32_t q = 0; q < W; q++) {
                np[q] = p[q] & nv[q];
                nx[q] = x[q] & nv[q];
            }
            s->r[s->nr++] = v;
            int rc = bk(s, np, nx);
            s->nr--;
            if (rc) { frep_free(np); return -1; }
            p[w] &= ~((uint64_t)1 << (v % 64));
            x[w] |= (uint64_t)1 << (v % 64);
        }
    }
    frep_free(np);
    return 0;
}

int part_cliques(const gp_graph *g, uint32_t max_cliques, gp_cliques *out)
{
    memset(out, 0, sizeof *out);
    bk_state s;
    memset(&s, 0, sizeof s);
    s.g = g;
    s.max = max_cliques;
    uint32_t W = g->words ? g->words : 1;
    s.r = frep_malloc((size_t)(g->n ? g->n : 1) * sizeof *s.r);
    uint64_t *p = frep_calloc((size_t)2 * W, sizeof *p);
    if (!s.r || !p) {
        frep_free(s.r);
        frep_free(p);
        return -1;
    }
    for (uint32_t i = 0; i < g->n; i++) p[i / 64] |= (uint64_t)1 << (i % 64);
    int rc = g->n ? bk(&s, p, p + W) : 0;
    frep_free(p);
    frep_free(s.r);
    if (rc) {
        frep_free(s.start);
        frep_free(s.members);
        return s.nomem ? -1 : 1;
    }
    if (!s.start) {
        s.start = frep_calloc(1, sizeof *s.start);
        if (!s.start) return -1;
    }
    out->count = s.count;
    out->start = s.start;
    out->members = s.members;
    return 0;
}

void part_cliques_free(gp_cliques *c)
{
    frep_free(c->start);
    frep_free(c->members);
    memset(c, 0, sizeof *c);
}

/* ---- merging ---------------------------------------------------------------------- */

static int is_union(uint8_t op) { return op == FREP_OP_MAX || op == FREP_OP_RUNI; }
static int is_sub(uint8_t op) { return op == FREP_OP_MSUB || op == FREP_OP_RSUB; }

int part_graft_valid(const frep_insn *code, uint32_t len, uint32_t target)
{
    if (!len || target >= len) return 0;
    uint32_t cur = len - 1;
    while (cur != target) {
        const frep_insn *in = &code[cur];
        if (tree_nin(in) != 2) return 0;  /* a leaf, or under a complement */
        uint32_t l0, l1, r0;
        tree_operands(code, cur, &l0, &l1, &r0);
        if (target >= l0 && target <= l1) {
            if (!is_union(in->op) && !is_sub(in->op)) return 0;
            cur = l1;
        } else if (target >= r0 && target < cur) {
            if (!is_union(in->op)) return 0;
            cur = cur - 1;
        } else {
            return 0;
        }
    }
    return 1;
}

uint32_t part_largest_common(const gp_tree *a, const gp_tree *b, uint32_t *ea,
                             uint32_t *eb)
{
    uint32_t best = 0;
    *ea = *eb = 0;
    uint32_t *sb = frep_malloc((size_t)(b->len ? b->len : 1) * sizeof *sb);
    if (!sb) return 0;
    for (uint32_t j = 0; j < b->len; j++) sb[j] = tree_subtree_start(b->code, j);
    for (uint32_t i = 0; i < a->len; i++) {
        uint32_t na = i - tree_subtree_start(a->code, i) + 1;
        if (na <= best) continue;
        for (uint32_t j = 0; j < b->len; j++) {
            if (j - sb[j] + 1 != na) continue;
            if (tree_compare(a->code, i, b->code, j) == 0) {
                best = na;
                *ea = i;
                *eb = j;
                break;
            }
        }
    }
    frep_free(sb);
    return best;
}

/* out = host with the subtree ending at `at` replaced by all of t. */
static int graft(gp_tree *out, const gp_tree *host, uint32_t at, const gp_tree *t)
{
    if (tree_copy(out, host)) return -1;
    return tree_splice(out, tree_subtree_start(host->code, at), at, t->code, t->len);
}

static int join(gp_tree *out, const gp_tree *a, const gp_tree *b, uint8_t op)
{
    out->len = 0;
    if (tree_reserve(out, a->len + b->len + 1)) return -1;
    memcpy(out->code, a->code, (size_t)a->len * sizeof *a->code);
    memcpy(out->code + a->len, b->code, (size_t)b->len * sizeof *b->code);
    out->len = a->len + b->len;
    return tree_push(out, (frep_opcode)op, 0);
}

int part_merge_pair(const gp_tree *a, const gp_tree *b, gp_setops s, const gp_cache *c,
                    gp_eval *e, gp_tree *out, double *fitness, gp_cancel *cancel)
{
    gp_opset o = gp_opset_of(s);
    gp_tree cand[4];
    memset(cand, 0, sizeof cand);
    int nc = 0, rc = -1;
    uint32_t ea, eb;
    if (part_largest_common(a, b, &ea, &eb)) {
        /* b contains the common part where a graft keeps b's shape: put all of b
         * in place of it inside a (and the other way round). */
        if (part_graft_valid(b->code, b->len, eb) && graft(&cand[nc++], a, ea, b)) goto out;
        if (part_graft_valid(a->code, a->len, ea) && graft(&cand[nc++], b, eb, a)) goto out;
    }
    if (join(&cand[nc++], a, b, o.uni) || join(&cand[nc++], a, b, o.inter)) goto out;
    int best = -1;
    double bf = -HUGE_VAL;
    for (int k = 0; k < nc; k++) {
        if (simplify_rules(&cand[k], s)) goto out;
        double f;
        if (gp_fitness(c, e, cand[k].code, cand[k].len, &f)) goto out;
        if (best < 0 || f > bf) {
            best = k;
            bf = f;
        }
    }
    if (tree_copy(out, &cand[best]) || simplify_tree_both(out, s, c, e, fitness, cancel)) goto out;
    rc = 0;
out:
    for (int k = 0; k < 4; k++) tree_free(&cand[k]);
    return rc;
}

/* ---- the whole acceleration --------------------------------------------------------- */

/* One piece of the partition: a tree over global primitive numbers, the points it
 * explains (ascending indices into the cache) and its primitives (ascending). */
typedef struct part_piece {
    gp_tree t;
    size_t *pts;
    size_t npts;
    uint32_t *prims;
    uint32_t nprims;
} part_piece;

static void piece_free(part_piece *p)
{
    tree_free(&p->t);
    frep_free(p->pts);
    frep_free(p->prims);
    memset(p, 0, sizeof *p);
}

static uint64_t mix_seed(uint64_t seed, uint64_t k)
{
    uint64_t z = seed + 0x9e3779b97f4a7c15u * (k + 1);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9u;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebu;
    return z ^ (z >> 31);
}

static uint32_t low_bit(uint32_t x)
{
    uint32_t i = 0;
    while (!(x & 1u)) {
        x >>= 1;
        i++;
    }
    return i;
}

/* Fitness of the tree of `leaves` (1: a tree of the forest; 2: two trees and op) of
 * expanded length tl, in *fit: from e's tape of the forest when it has values, else in
 * full. floor as in gp_fitness_replaced. 0 or -1 (allocation). */
static int exh_fitness(const gp_cache *c, gp_eval *e, const gp_tree *forest,
                       const uint32_t *ends, int nl, uint8_t op, uint32_t tl,
                       gp_tree *scratch, double floor, double *fit)
{
    scratch->len = 0;
    if (gp_tape_valued(c, e)) {
        for (int q = 0; q < nl; q++) {
            frep_insn lf = gp_tape_leaf(c, ends[q]);
            if (tree_push(scratch, (frep_opcode)lf.op, lf.arg)) return -1;
        }
        if (nl == 2 && tree_push(scratch, (frep_opcode)op, 0)) return -1;
        double pen = c->lambda * (double)tl, sc;
        if (gp_score_taped(c, e, scratch->code, scratch->len, floor + pen, &sc)) return -1;
        *fit = sc - pen;
        return 0;
    }
    for (int q = 0; q < nl; q++) {
        uint32_t s0 = tree_subtree_start(forest->code, ends[q]);
        uint32_t n = ends[q] - s0 + 1;
        if (tree_reserve(scratch, scratch->len + n + 1)) return -1;
        memcpy(scratch->code + scratch->len, forest->code + s0, n * sizeof *scratch->code);
        scratch->len += n;
    }
    if (nl == 2 && tree_push(scratch, (frep_opcode)op, 0)) return -1;
    return gp_fitness(c, e, scratch->code, scratch->len, fit);
}

/* One part_exhaustive: the forest of the trees over every proper subset S of the
 * clique (each 2|S| - 1 instructions, subsets by size so that each comes after its
 * parts: off[S] is the first one's pc, count[S] their number) and the best tree so
 * far (best_nl trees of the forest, joined by best_op when two). */
typedef struct exh_state {
    const gp_cache *c;
    gp_eval *e;
    gp_opset o;
    uint32_t k, full;        /* clique size; the full set's bits */
    uint32_t off[1u << PART_EXHAUSTIVE_MAX], count[1u << PART_EXHAUSTIVE_MAX];
    gp_tree forest, scratch;
    double bf;               /* best fitness (valid when have) */
    int have;
    uint32_t best[2], best_nl;
    uint8_t best_op;
} exh_state;

/* Append to the forest the trees over S from its splits S = A + B (A holding S's
 * lowest member, each split once): a | b, a & b, a \ b, b \ a for every tree a over A
 * and b over B. */
static int exh_grow_set(exh_state *x, uint32_t S)
{
    gp_tree *f = &x->forest;
    uint32_t low = S & (0u - S);
    for (uint32_t A = (S - 1) & S; A; A = (A - 1) & S) {
        if (!(A & low)) continue;
        uint32_t B = S ^ A;
        uint32_t la = 2 * popcount64(A) - 1, lb = 2 * popcount64(B) - 1;
        for (uint32_t ia = 0; ia < x->count[A]; ia++)
            for (uint32_t ib = 0; ib < x->count[B]; ib++)
                for (int w = 0; w < 4; w++) {
                    uint32_t a0 = x->off[A] + ia * la, b0 = x->off[B] + ib * lb;
                    uint32_t p = w == 3 ? b0 : a0, lp = w == 3 ? lb : la;  /* b \ a */
                    uint32_t q = w == 3 ? a0 : b0, lq = w == 3 ? la : lb;
                    uint8_t op = w == 0 ? x->o.uni : w == 1 ? x->o.inter : x->o.sub;
                    if (tree_reserve(f, f->len + lp + lq + 1)) return -1;
                    /* Copied from the forest itself: index, not pointer. */
                    memmove(f->code + f->len, f->code + p, lp * sizeof *f->code);
                    memmove(f->code + f->len + lp, f->code + q, lq * sizeof *f->code);
                    f->len += lp + lq;
                    if (tree_push(f, (frep_opcode)op, 0)) return -1;
                    x->count[S]++;
                }
    }
    return 0;
}

/* The forest of every proper subset (the single leaf for a clique of one), and its
 * tape. */
static int exh_forest(exh_state *x)
{
    for (uint32_t size = 1; size < x->k; size++)
        for (uint32_t S = 1; S < x->full; S++) {
            if (popcount64(S) != size) continue;
            x->off[S] = x->forest.len;
            if (size == 1) {
                if (tree_push(&x->forest, FREP_OP_PRIM, low_bit(S))) return -1;
                x->count[S] = 1;
            } else if (exh_grow_set(x, S)) {
                return -1;
            }
        }
    if (x->k == 1 && tree_push(&x->forest, FREP_OP_PRIM, 0)) return -1;
    return gp_tape_record(x->c, x->e, x->forest.code, x->forest.len, NULL);
}

/* The fittest tree of the forest, subsets by size (ties: the first, so the
 * shortest). */
static int exh_best_single(exh_state *x)
{
    uint32_t k = x->k, nsets = 1u << k;
    for (uint32_t size = 1; size < k || (k == 1 && size == 1); size++)
        for (uint32_t S = 1; S < nsets; S++) {
            if (popcount64(S) != size || (S == x->full && k > 1)) continue;
            uint32_t tl = 2 * size - 1;
            for (uint32_t q = 0; q < x->count[S] || (k == 1 && q == 0); q++) {
                uint32_t end = x->off[S] + q * tl + tl - 1;
                double f;
                if (exh_fitness(x->c, x->e, &x->forest, &end, 1, 0, tl, &x->scratch,
                                x->have ? x->bf : -HUGE_VAL, &f))
                    return -1;
                if (!x->have || f > x->bf) {
                    x->bf = f;
                    x->have = 1;
                    x->best[0] = end;
                    x->best_nl = 1;
                }
            }
        }
    return 0;
}

/* The trees over all k primitives, two trees of the forest and an operation each,
 * scored from the forest's tape; kept when fitter. */
static int exh_best_full(exh_state *x)
{
    uint32_t tl = 2 * x->k - 1, low = 1, full = x->full;
    for (uint32_t A = (full - 1) & full; A; A = (A - 1) & full) {
        if (!(A & low)) continue;
        uint32_t B = full ^ A;
        uint32_t la = 2 * popcount64(A) - 1, lb = 2 * popcount64(B) - 1;
        for (uint32_t ia = 0; ia < x->count[A]; ia++)
            for (uint32_t ib = 0; ib < x->count[B]; ib++)
                for (int w = 0; w < 4; w++) {
                    uint32_t ea = x->off[A] + ia * la + la - 1, eb = x->off[B] + ib * lb + lb - 1;
                    uint32_t ends[2] = { w == 3 ? eb : ea, w == 3 ? ea : eb };
                    uint8_t op = w == 0 ? x->o.uni : w == 1 ? x->o.inter : x->o.sub;
                    double f;
                    if (exh_fitness(x->c, x->e, &x->forest, ends, 2, op, tl, &x->scratch,
                                    x->bf, &f))
                        return -1;
                    if (f > x->bf) {
                        x->bf = f;
                        x->best[0] = ends[0];
                        x->best[1] = ends[1];
                        x->best_nl = 2;
                        x->best_op = op;
                    }
                }
    }
    return 0;
}

/* The winner, expanded from the forest into t. */
static int exh_expand(const exh_state *x, gp_tree *t)
{
    t->len = 0;
    for (uint32_t q = 0; q < x->best_nl; q++) {
        uint32_t s0 = tree_subtree_start(x->forest.code, x->best[q]);
        uint32_t n = x->best[q] - s0 + 1;
        if (tree_reserve(t, t->len + n + 1)) return -1;
        memcpy(t->code + t->len, x->forest.code + s0, n * sizeof *t->code);
        t->len += n;
    }
    if (x->best_nl == 2 && tree_push(t, (frep_opcode)x->best_op, 0)) return -1;
    return 0;
}

int part_exhaustive(gp_setops s, const gp_cache *c, gp_eval *e, gp_tree *t)
{
    uint32_t k = c->nprims;
    if (k == 0 || k > PART_EXHAUSTIVE_MAX) return -1;
    exh_state st;
    memset(&st, 0, sizeof st);
    exh_state *x = &st;
    x->c = c;
    x->e = e;
    x->o = gp_opset_of(s);
    x->k = k;
    x->full = (1u << k) - 1;
    x->bf = -HUGE_VAL;
    int rc = exh_forest(x) || exh_best_single(x) || (k > 1 && exh_best_full(x)) ||
                     exh_expand(x, t)
                 ? -1
                 : 0;
    tree_free(&x->forest);
    tree_free(&x->scratch);
    return rc;
}

/* Solve one clique: a tree over its members (global numbers) in *t. */
static int solve_clique(const gp_config *cfg, const gp_cache *c, const uint32_t *mem,
                        uint32_t k, const size_t *pts, size_t npts, uint64_t qseed,
                        gp_eval *e, gp_tree *t, uint32_t *gens)
{
    gp_cache *sc = gp_cache_subset(c, pts, npts, mem, k, -1);
    if (!sc) return -1;
    int rc = -1;
    t->len = 0;
    *gens = 0;
    if (k == 1) {
        if (tree_push(t, FREP_OP_PRIM, 0)) goto out;
    } else if (k <= PART_EXHAUSTIVE_MAX) {
        if (part_exhaustive(cfg->setops, sc, e, t)) goto out;
        if (k > 2 && simplify_tree(t, cfg->setops, sc, e, NULL, cfg->cancel)) goto out;
    } else {
        gp_config cc = *cfg;
        cc.threads = 1;
        cc.seed = qseed;
        cc.max_depth = gp_default_depth(k);
        gp_result r;
        if (gp_run(&cc, sc, NULL, 0, NULL, NULL, &r)) {
            tree_free(&r.best);
            goto out;
        }
        *gens = r.generations;
        int bad = tree_copy(t, &r.best);
        tree_free(&r.best);
        if (bad || simplify_tree(t, cfg->setops, sc, e, NULL, cfg->cancel)) goto out;
    }
    tree_renumber(t, mem, k, 1);
    rc = 0;
out:
    gp_cache_free(sc);
    return rc;
}

static size_t merge_sorted(const size_t *a, size_t na, const size_t *b, size_t nb, size_t *o)
{
    size_t i = 0, j = 0, n = 0;
    while (i < na || j < nb) {
        if (j >= nb || (i < na && a[i] < b[j])) o[n++] = a[i++];
        else if (i >= na || b[j] < a[i]) o[n++] = b[j++];
        else { o[n++] = a[i++]; j++; }
    }
    return n;
}

static uint32_t shared_count(const part_piece *a, const part_piece *b)
{
    uint32_t i = 0, j = 0, n = 0;
    while (i < a->nprims && j < b->nprims) {
        if (a->prims[i] < b->prims[j]) i++;
        else if (b->prims[j] < a->prims[i]) j++;
        else { n++; i++; j++; }
    }
    return n;
}

/* Merge piece j into piece i. */
static int merge_pieces(const gp_config *cfg, const gp_cache *c, gp_eval *e,
                        part_piece *pi, part_piece *pj)
{
    size_t *u = frep_malloc((pi->npts + pj->npts + 1) * sizeof *u);
    if (!u) return -1;
    size_t nu = merge_sorted(pi->pts, pi->npts, pj->pts, pj->npts, u);
    gp_tree both = { NULL, 0, 0 }, a = { NULL, 0, 0 }, b = { NULL, 0, 0 }, m = { NULL, 0, 0 };
    uint32_t *prims = NULL;
    gp_cache *sc = NULL;
    int rc = -1;
    if (join(&both, &pi->t, &pj->t, FREP_OP_MAX)) goto out;
    uint32_t k = tree_used_prims(&both, c->nprims, &prims);
    if (!prims) goto out;
    sc = gp_cache_subset(c, u, nu, prims, k, -1);
    if (!sc || tree_copy(&a, &pi->t) || tree_copy(&b, &pj->t)) goto out;
    tree_renumber(&a, prims, k, 0);
    tree_renumber(&b, prims, k, 0);
    if (part_merge_pair(&a, &b, cfg->setops, sc, e, &m, NULL, cfg->cancel)) goto out;
    tree_renumber(&m, prims, k, 1);
    if (tree_copy(&pi->t, &m)) goto out;
    frep_free(pi->pts);
    pi->pts = u;
    pi->npts = nu;
    u = NULL;
    frep_free(pi->prims);
    pi->nprims = tree_used_prims(&pi->t, c->nprims, &pi->prims);
    if (!pi->prims) goto out;
    rc = 0;
out:
    frep_free(u);
    frep_free(prims);
    gp_cache_free(sc);
    tree_free(&both);
    tree_free(&a);
    tree_free(&b);
    tree_free(&m);
    return rc;
}

/* Primitives that explain point i alone, as themselves or complemented (|f| < eps_d,
 * normal within alpha of -grad f or of grad f): own[j] = 1. Returns their number. */
static uint32_t point_owners(const gp_cache *c, size_t i, uint8_t *own)
{
    uint32_t k = 0;
    double ca = cos(c->alpha);
    const double *nn = c->nrm + 3 * i;
    for (uint32_t j = 0; j < c->nprims; j++) {
        double f = c->v[(size_t)j * c->n + i];
        if (!(fabs(f) < c->eps_d)) continue;
        double g[3] = { c->g[(3 * (size_t)j) * c->n + i], c->g[(3 * (size_t)j + 1) * c->n + i],
                        c->g[(3 * (size_t)j + 2) * c->n + i] };
        double gl = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
        if (!(gl > 0)) continue;
        if (fabs(g[0] * nn[0] + g[1] * nn[1] + g[2] * nn[2]) / gl > ca) {
            own[j] = 1;
            k++;
        }
    }
    return k;
}

/* One part_run: the cliques, one piece per clique, the evaluators. */
typedef struct part_ctx {
    const gp_config *cfg;
    const gp_cache *c;
    const double *x, *y, *z;  /* the cache's points */
    const gp_obb *boxes;
    double margin;
    gp_progress_fn fn;
    void *user;
    gp_result *res;
    part_info *info;
    double t0;                /* frep_now_seconds() at the start */
    gp_cliques cl;
    uint32_t nq;              /* cliques */
    part_piece *pc;           /* pc[q]: clique q's points, primitives and tree */
    uint32_t *gens;           /* GA generations per clique */
    int nthreads;
    gp_eval **ev;             /* one per thread */
    uint32_t live;            /* pieces left to merge (pc[0..live)) */
} part_ctx;

/* Overlap graph of the proxies and its maximal cliques. 1: not worth partitioning
 * (too many cliques, or one). */
static int part_find_cliques(part_ctx *s)
{
    part_info *info = s->info;
    gp_graph g;
    if (part_overlap_graph(s->boxes, s->c->nprims, s->margin, &g)) return -1;
    for (uint32_t i = 0; i < g.n; i++)
        for (uint32_t j = i + 1; j < g.n; j++) info->nedges += (uint32_t)part_graph_has(&g, i, j);
    int cr = part_cliques(&g, PART_MAX_CLIQUES, &s->cl);
    part_graph_free(&g);
    if (cr) return cr;  /* -1, or 1: too many cliques (unpartitioned GA) */
    info->ncliques = s->cl.count;
    for (uint32_t q = 0; q < s->cl.count; q++) {
        uint32_t k = s->cl.start[q + 1] - s->cl.start[q];
        if (k > info->largest) info->largest = k;
    }
    s->nq = s->cl.count;
    return s->cl.count <= 1;
}

/* The pieces and one evaluator per thread. */
static int part_alloc(part_ctx *s)
{
    s->pc = frep_calloc(s->nq, sizeof *s->pc);
    s->gens = frep_calloc(s->nq, sizeof *s->gens);
    s->nthreads = frep_threads(s->cfg->threads);
    s->ev = frep_calloc((size_t)s->nthreads, sizeof *s->ev);
    if (!s->pc || !s->gens || !s->ev) return -1;
    for (int i = 0; i < s->nthreads; i++)
        if (!(s->ev[i] = gp_eval_new())) return -1;
    return 0;
}

/* Point i in pass 0 (bestcnt[i]: the most member boxes of an eligible clique holding
 * it) or pass 1 (i joins the eligible cliques that hold it that often). own: scratch,
 * all 0 on entry and exit. */
static int part_assign_point(part_ctx *s, size_t i, int pass, uint8_t *own, uint32_t *bestcnt)
{
    const gp_cache *c = s->c;
    const gp_cliques *cl = &s->cl;
    double p[3] = { s->x[i], s->y[i], s->z[i] };
    uint32_t nown = point_owners(c, i, own);
    int failed = 0;
    for (uint32_t q = 0; q < s->nq; q++) {
        const uint32_t *mem = cl->members + cl->start[q];
        uint32_t k = cl->start[q + 1] - cl->start[q], cnt = 0, has_owner = 0;
        for (uint32_t m = 0; m < k; m++) {
            cnt += (uint32_t)part_obb_contains(&s->boxes[mem[m]], p, s->margin);
            has_owner |= own[mem[m]];
        }
        if (nown && !has_owner) continue;
        if (pass == 0) {
            if (cnt > bestcnt[i]) bestcnt[i] = cnt;
            continue;
        }
        part_piece *pq = &s->pc[q];
        if (cnt > 0 && (nown == 0 || cnt == bestcnt[i])) {
            if (!pq->pts) {
                pq->pts = frep_malloc((c->n ? c->n : 1) * sizeof *pq->pts);
                if (!pq->pts) failed = 1;
            }
            if (pq->pts) pq->pts[pq->npts++] = i;
        }
    }
    for (uint32_t j = 0; j < c->nprims; j++) own[j] = 0;
    return failed ? -1 : 0;
}

/* Points of each clique: inside the grown box of one of its members. A point that a
 * primitive explains (its owners) goes only to the cliques holding an owner whose
 * members' boxes contain it most often: a plane shared by several parts brings each
 * part's face to that part's clique, not to every clique of the plane (where the
 * clique's correct tree cannot explain it and the GA is pushed to wrong ones). Then
 * each piece's primitives, the clique's members. */
static int part_assign_points(part_ctx *s)
{
    const gp_cache *c = s->c;
    uint8_t *owner = frep_calloc(c->nprims ? c->nprims : 1, 1);
    uint32_t *bestcnt = frep_calloc(c->n ? c->n : 1, sizeof *bestcnt);
    int failed = !owner || !bestcnt;
    for (int pass = 0; pass < 2 && owner && bestcnt; pass++)
        for (size_t i = 0; i < c->n; i++)
            if (part_assign_point(s, i, pass, owner, bestcnt)) failed = 1;
    frep_free(owner);
    frep_free(bestcnt);
    if (failed) return -1;
    for (uint32_t q = 0; q < s->nq; q++) {
        const uint32_t *mem = s->cl.members + s->cl.start[q];
        uint32_t k = s->cl.start[q + 1] - s->cl.start[q];
        s->pc[q].prims = frep_malloc((size_t)k * sizeof *s->pc[q].prims);
        if (!s->pc[q].prims) return -1;
        memcpy(s->pc[q].prims, mem, (size_t)k * sizeof *mem);
        s->pc[q].nprims = k;
    }
    return 0;
}

/* How often the calling thread, idle while the last clique GAs run, polls the cancel
 * callback: well under FREP_CANCEL_POLL_SECONDS, and rare enough to cost nothing. */
#define PART_CANCEL_WAIT_SECONDS 0.005

static void part_wait(void)
{
    struct timespec ts = { 0, (long)(PART_CANCEL_WAIT_SECONDS * 1e9) };
    nanosleep(&ts, NULL);
}

/* Clique q's tree (solve_clique); 1 when it failed (memory). After a cancel a clique
 * not started yet is dropped; a running one stops at its next generation with its
 * best tree. */
static int part_solve_one(part_ctx *s, uint32_t q, int tid)
{
    part_piece *pq = &s->pc[q];
    if (pq->npts == 0) return 0;  /* explains no point: dropped */
    if (gp_cancelled(s->cfg->cancel)) return 0;
    return solve_clique(s->cfg, s->c, pq->prims, pq->nprims, pq->pts, pq->npts,
                        mix_seed(s->cfg->seed, q), s->ev[tid], &pq->t, &s->gens[q]) != 0;
}

/* A tree per clique, cliques in parallel (each taken from a shared counter), each
 * seeded from the run's seed and its number, so the trees do not depend on the
 * threads; a clique without points is dropped. The calling thread (thread 0), once
 * no clique is left to start, keeps polling the cancel callback every
 * PART_CANCEL_WAIT_SECONDS until the others end, so that a cancel reaches the clique
 * GAs still running. */
static int part_solve(part_ctx *s)
{
    int failed = 0;
    uint32_t next = 0, done = 0, nq = s->nq;
#pragma omp parallel num_threads(s->nthreads)
    {
        int tid = frep_thread_num();
        for (;;) {
            uint32_t q;
#pragma omp atomic capture
            q = next++;
            if (q >= nq) break;
            if (part_solve_one(s, q, tid)) {
#pragma omp atomic write
                failed = 1;
            }
#pragma omp atomic update
            done++;
        }
        for (;;) {
            uint32_t d;
#pragma omp atomic read
            d = done;
            if (tid != 0 || d >= nq) break;
            gp_cancelled(s->cfg->cancel);
            part_wait();
        }
    }
    if (failed) return -1;
    for (uint32_t q = 0; q < s->nq; q++) s->info->generations += s->gens[q];
    return 0;
}

/* The pieces with a tree moved to the front (s->live of them), their primitives those
 * the tree uses. */
static int part_compact(part_ctx *s)
{
    part_piece *pc = s->pc;
    uint32_t live = 0;
    for (uint32_t q = 0; q < s->nq; q++) {
        if (pc[q].t.len) {
            frep_free(pc[q].prims);
            pc[q].nprims = tree_used_prims(&pc[q].t, s->c->nprims, &pc[q].prims);
            if (!pc[q].prims) return -1;
            if (live != q) {
                pc[live] = pc[q];
                memset(&pc[q], 0, sizeof pc[q]);
            }
            live++;
        } else {
            piece_free(&pc[q]);
        }
    }
    s->live = live;
    return 0;
}

/* After Ctrl-C: the pieces left joined by plain unions into piece 0 at once (no search),
 * so that the tree still covers every clique solved. */
static int part_union_rest(part_ctx *s)
{
    part_piece *pc = s->pc;
    uint8_t uni = gp_opset_of(s->cfg->setops).uni;
    gp_tree both = { NULL, 0, 0 };
    for (uint32_t q = 1; q < s->live; q++) {
        if (join(&both, &pc[0].t, &pc[q].t, uni) || tree_copy(&pc[0].t, &both)) {
            tree_free(&both);
            return -1;
        }
        piece_free(&pc[q]);
    }
    tree_free(&both);
    s->live = 1;
    return 0;
}

/* Merge: repeatedly the two pieces sharing the most primitives (ties: first), with a
 * report after each merge (a stop request ends the merging); Ctrl-C unites the rest. */
static int part_merge_all(part_ctx *s)
{
    part_piece *pc = s->pc;
    while (s->live > 1) {
        if (gp_cancelled(s->cfg->cancel)) return part_union_rest(s);
        uint32_t live = s->live, bi = 0, bj = 1, bs = 0;
        for (uint32_t i = 0; i < live; i++)
            for (uint32_t j = i + 1; j < live; j++) {
                uint32_t sh = shared_count(&pc[i], &pc[j]);
                if (sh > bs) { bs = sh; bi = i; bj = j; }
            }
        if (merge_pieces(s->cfg, s->c, s->ev[0], &pc[bi], &pc[bj])) return -1;
        piece_free(&pc[bj]);
        memmove(&pc[bj], &pc[bj + 1], (size_t)(live - bj - 1) * sizeof *pc);
        memset(&pc[live - 1], 0, sizeof *pc);
        s->live--;
        if (s->fn) {
            gp_progress pr = { s->info->generations, NAN, pc[bi].t.len, frep_now_seconds() - s->t0,
                               GP_PHASE_MERGE, 0, 0 };
            if (s->fn(s->user, &pr)) return part_union_rest(s);
        }
    }
    return 0;
}

/* The merged tree simplified over the whole cache (both orders), and its report. */
static int part_final(part_ctx *s)
{
    gp_result *res = s->res;
    double fit;
    if (tree_copy(&res->best, &s->pc[0].t)) return -1;
    if (gp_cancelled(s->cfg->cancel)) {  /* Ctrl-C: the tree as merged */
        if (gp_fitness(s->c, s->ev[0], res->best.code, res->best.len, &fit)) return -1;
    } else if (simplify_tree_both(&res->best, s->cfg->setops, s->c, s->ev[0], &fit,
                                  s->cfg->cancel)) {
        return -1;
    }
    res->fitness = fit;
    res->generations = s->info->generations;
    res->stop = GP_STOP_GENERATIONS;
    s->info->partitioned = 1;
    if (s->fn) {
        gp_progress pr = { s->info->generations, fit, res->best.len, frep_now_seconds() - s->t0,
                           GP_PHASE_MERGED, 0, 0 };
        if (s->cfg->report_explained && gp_progress_explained(s->c, s->ev[0], &res->best, &pr))
            return -1;
        s->fn(s->user, &pr);  /* a stop request reaches the polish's first report */
    }
    return 0;
}

/* The steps after the cliques: points per clique, a tree per clique, the merge, the
 * merged tree. */
static int part_stages(part_ctx *s)
{
    if (part_alloc(s) || part_assign_points(s)) return -1;
    if (s->fn) {  /* a stop request raises the flag the clique GAs poll */
        gp_progress pr = { 0, NAN, 0, frep_now_seconds() - s->t0, GP_PHASE_CLIQUES, 0, 0 };
        s->fn(s->user, &pr);
    }
    if (part_solve(s) || part_compact(s)) return -1;
    if (s->live == 0) return 0;  /* no clique tree: the unpartitioned GA */
    if (part_merge_all(s)) return -1;
    return part_final(s);
}

int part_run(const gp_config *cfg, const gp_cache *c, const double *x, const double *y,
             const double *z, const gp_obb *boxes, double margin, gp_progress_fn fn,
             void *user, gp_result *res, part_info *info)
{
    memset(info, 0, sizeof *info);
    memset(res, 0, sizeof *res);
    res->fitness = -HUGE_VAL;
    part_ctx s;
    memset(&s, 0, sizeof s);
    s.cfg = cfg;
    s.c = c;
    s.x = x;
    s.y = y;
    s.z = z;
    s.boxes = boxes;
    s.margin = margin;
    s.fn = fn;
    s.user = user;
    s.res = res;
    s.info = info;
    s.t0 = frep_now_seconds();
    int r = part_find_cliques(&s);
    int rc = r < 0 ? -1 : r > 0 ? 0 : part_stages(&s);
    if (s.pc)
        for (uint32_t q = 0; q < s.nq; q++) piece_free(&s.pc[q]);
    frep_free(s.pc);
    frep_free(s.gens);
    if (s.ev)
        for (int i = 0; i < s.nthreads; i++) gp_eval_free(s.ev[i]);
    frep_free(s.ev);
    part_cliques_free(&s.cl);
    return rc;
}
