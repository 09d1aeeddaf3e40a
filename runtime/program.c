/* program.c - building, checking, querying and disassembling frep_programs.
 *
 * The compiler (lang/emit.c) and the genetic-programming engine (evolve/) assemble
 * bytecode with prog_emit() and seal it with prog_finish(), which verifies the stack
 * discipline so the evaluators (runtime/vm*.c) can run it without checks.  The opcode
 * queries and the disassembler's mnemonics come from the FREP_OPS table of ops.h; the
 * operand checks and operand text name the ops with special fields.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "buf.h"
#include "cancel.h"
#include "program.h"

/* ---- the opcode table, expanded -------------------------------------------- */

typedef struct op_info {
    const char *name;
    const char *meaning;
    int nin;
    unsigned flags;
} op_info;

static const op_info op_table[FREP_OP__COUNT] = {
#define FREP_OP_INFO(name, id, nin, flags, meaning) [id] = {#name, meaning, nin, flags},
    FREP_OPS(FREP_OP_INFO)
#undef FREP_OP_INFO
};

static int op_valid(frep_opcode op)
{
    return (unsigned)op < FREP_OP__COUNT && op_table[op].name != NULL;
}

const char *op_name(frep_opcode op) { return op_valid(op) ? op_table[op].name : "?"; }
const char *op_meaning(frep_opcode op) { return op_valid(op) ? op_table[op].meaning : "?"; }
int op_nin(frep_opcode op) { return op_valid(op) ? op_table[op].nin : 0; }
unsigned op_flags(frep_opcode op) { return op_valid(op) ? op_table[op].flags : 0; }

int op_pushes(frep_opcode op)
{
    if (op == FREP_OP_STORE || op == FREP_OP_JMP || op == FREP_OP_JZ || op == FREP_OP_STOREI)
        return 0;
    return op_valid(op) ? 1 : 0;
}

int insn_nin(const frep_insn *in)
{
    int n = op_nin((frep_opcode)in->op);
    if (n == 2 && (in->flags & (INSN_KA | INSN_KB))) n = 1;
    return n;
}

uint32_t prog_subtree_start(const frep_insn *code, uint32_t end)
{
    long need = 1;
    uint32_t pc = end;
    for (;;) {
        need -= op_pushes((frep_opcode)code[pc].op);
        need += insn_nin(&code[pc]);
        if (need <= 0 || pc == 0) return pc;
        --pc;
    }
}

/* ---- building ---------------------------------------------------------------- */

/* Initial instruction capacity; doubled as needed. */
#define PROG_INITIAL_CAP 64u

frep_program *prog_new(void)
{
    return frep_calloc(1, sizeof(frep_program));
}

uint32_t prog_emit(frep_program *p, frep_opcode op, uint32_t arg, double k, uint8_t flags,
                   frep_srcpos pos)
{
    if (p->ncode >= UINT32_MAX / 4) return UINT32_MAX;
    /* Code built elsewhere (evolve/ splices its own arrays) may have cap 0 or no pos:
     * grow both and give earlier instructions "no position". */
    if (p->ncode >= p->cap || !p->code || !p->pos) {
        uint32_t ncap = p->ncode < PROG_INITIAL_CAP ? PROG_INITIAL_CAP : 2 * p->ncode;
        frep_insn *c;
        frep_srcpos *ps;
        int had_pos = p->pos != NULL;
        if (ncap < p->cap) ncap = p->cap;
        c = frep_realloc(p->code, ncap * sizeof *c);
        if (!c) return UINT32_MAX;
        p->code = c;
        ps = frep_realloc(p->pos, ncap * sizeof *ps);
        if (!ps) return UINT32_MAX;
        if (!had_pos && p->ncode) memset(ps, 0, p->ncode * sizeof *ps);
        p->pos = ps;
        p->cap = ncap;
    }
    {
        frep_insn *in = &p->code[p->ncode];
        memset(in, 0, sizeof *in);
        in->op = (uint8_t)op;
        in->flags = flags;
        in->arg = arg;
        in->k = k;
        p->pos[p->ncode] = pos;
    }
    return p->ncode++;
}

/* Check one instruction's operands against the program; may grow nslots/nprims so
 * that hand-assembled programs need not set them. */
static int prog_check_insn(frep_program *p, const frep_insn *in, uint32_t pc)
{
    frep_opcode op = (frep_opcode)in->op;
    int nin = op_nin(op);
    if (!op_valid(op)) return -1;
    /* A switch over unsigned: only the ops with checked operands are listed. */
    if ((in->flags & (INSN_KA | INSN_KB)) == (INSN_KA | INSN_KB)) return -1;
    if ((in->flags & (INSN_KA | INSN_KB)) &&
        (nin != 2 || op == FREP_OP_AUNI || op == FREP_OP_AINT || (op_flags(op) & OPF_CTRL)))
        return -1; /* only plain binary ops have an immediate operand */
    switch ((unsigned)op) {
    case FREP_OP_X:
        if (in->arg > 2) return -1;
        break;
    case FREP_OP_PARAM:
        if (in->arg >= p->nparams) return -1;
        break;
    case FREP_OP_PRIM:
        if (in->arg >= p->nprims) p->nprims = in->arg + 1;
        break;
    case FREP_OP_LOAD: case FREP_OP_STORE:
        if (in->arg >= FREP_MAX_SLOTS) return -1;
        if (in->arg >= p->nslots) p->nslots = in->arg + 1;
        break;
    case FREP_OP_LOADI: case FREP_OP_STOREI: {
        double end = (double)in->arg + in->k;
        if (!(in->k >= 1) || !(end <= FREP_MAX_SLOTS) || in->k != floor(in->k)) return -1;
        if ((uint32_t)end > p->nslots) p->nslots = (uint32_t)end;
        break;
    }
    case FREP_OP_JMP: case FREP_OP_JZ:
        if (in->arg > p->ncode) return -1;
        break;
    default:
        break;
    }
    (void)pc;
    return 0;
}

/* The maximum stack depth of the code, by a worklist over the control-flow graph from
 * the depth before each pc (index ncode: at the end): every path must agree on the
 * depth at a join, none may underflow, and the program must leave exactly its one
 * result.  -1 when one of these fails or memory runs out. */
static long prog_max_depth(const frep_program *p)
{
    long *depth = frep_malloc((p->ncode + 1) * sizeof *depth);
    uint32_t *work = frep_malloc((p->ncode + 1) * sizeof *work);
    uint32_t nwork = 0, pc;
    long maxd = 0;
    int rc = 0;
    if (!depth || !work) { frep_free(depth); frep_free(work); return -1; }
    for (pc = 0; pc <= p->ncode; pc++) depth[pc] = -1;
    depth[0] = 0;
    work[nwork++] = 0;
    while (nwork > 0 && rc == 0) {
        uint32_t succ[2];
        int nsucc = 0, i;
        long d;
        const frep_insn *in;
        pc = work[--nwork];
        if (pc == p->ncode) continue;
        in = &p->code[pc];
        d = depth[pc] - insn_nin(in);
        if (d < 0) { rc = -1; break; }
        d += op_pushes((frep_opcode)in->op);
        if (d > maxd) maxd = d;
        if (in->op == FREP_OP_JMP) {
            succ[nsucc++] = in->arg;
        } else {
            succ[nsucc++] = pc + 1;
            if (in->op == FREP_OP_JZ) succ[nsucc++] = in->arg;
        }
        for (i = 0; i < nsucc; i++) {
            uint32_t s = succ[i];
            if (depth[s] < 0) {
                depth[s] = d;
                work[nwork++] = s;
            } else if (depth[s] != d) {
                rc = -1;
            }
        }
    }
    if (rc == 0 && depth[p->ncode] != 1) rc = -1;
    frep_free(depth);
    frep_free(work);
    return rc < 0 ? -1 : maxd;
}

int prog_finish(frep_program *p)
{
    uint32_t pc, flags = 0;
    long maxd;

    if (!p || p->ncode == 0 || !p->code) return -1;
    for (pc = 0; pc < p->ncode; pc++) {
        frep_opcode op = (frep_opcode)p->code[pc].op;
        if (prog_check_insn(p, &p->code[pc], pc) < 0) return -1;
        if (op == FREP_OP_JMP || op == FREP_OP_JZ) flags |= PROG_HAS_BRANCHES;
        if (op == FREP_OP_PRIM) flags |= PROG_HAS_PRIMS;
    }
    maxd = prog_max_depth(p);
    if (maxd < 0 || maxd > FREP_MAX_STACK) return -1;
    p->max_stack = (uint32_t)maxd;
    p->flags = flags;
    return 0;
}

void frep_program_free(frep_program *p)
{
    uint32_t i;
    if (!p) return;
    for (i = 0; i < p->nparams && p->params; i++) frep_free(p->params[i].name);
    frep_free(p->params);
    frep_free(p->code);
    frep_free(p->pos);
    frep_free(p->file);
    frep_free(p->model);
    for (i = 0; i < p->nattrs && p->attrs; i++) frep_program_free(p->attrs[i]);
    frep_free(p->attrs);
    if (p->owns_work) frep_free(p->work);
    frep_free(p);
}

/* ---- the work budget ------------------------------------------------------------ */

int prog_work_spent(const frep_work *w)
{
    return w && atomic_load_explicit(&w->used, memory_order_relaxed) > w->limit;
}

int prog_work_stop(const frep_work *w)
{
    return w && (prog_work_spent(w) || frep_cancelled(w->cancel));
}

/* The limit of a work record that only carries a cancel flag: never spent. */
#define PROG_NO_LIMIT UINT64_MAX

/* p's own work record (made when p has none), shared with its attribute programs;
 * NULL out of memory. */
static frep_work *work_own(frep_program *p)
{
    uint32_t i;
    if (!p->owns_work) {
        frep_work *w = frep_malloc(sizeof *w);
        if (!w) return NULL;
        w->limit = PROG_NO_LIMIT;
        atomic_init(&w->used, 0);
        w->cancel = NULL;
        p->work = w;
        p->owns_work = 1;
    }
    for (i = 0; i < p->nattrs && p->attrs; i++) {
        frep_program *a = p->attrs[i];
        if (a->owns_work) frep_free(a->work);
        a->work = p->work;
        a->owns_work = 0;
    }
    return p->work;
}

/* Drop p's work record when it neither limits nor cancels anything. */
static void work_drop_if_idle(frep_program *p)
{
    uint32_t i;
    if (!p->owns_work || p->work->limit != PROG_NO_LIMIT || p->work->cancel) return;
    frep_free(p->work);
    p->work = NULL;
    p->owns_work = 0;
    for (i = 0; i < p->nattrs && p->attrs; i++) p->attrs[i]->work = NULL;
}

int frep_program_set_work_limit(frep_program *p, uint64_t limit)
{
    frep_work *w;
    if (!p) return -1;
    if (limit == 0 && !p->owns_work) return 0;
    if (!(w = work_own(p))) return -1;
    w->limit = limit ? limit : PROG_NO_LIMIT;
    atomic_store_explicit(&w->used, 0, memory_order_relaxed);
    work_drop_if_idle(p);
    return 0;
}

int frep_program_set_cancel(frep_program *p, volatile sig_atomic_t *flag)
{
    frep_work *w;
    if (!p) return -1;
    if (!flag && !p->owns_work) return 0;
    if (!(w = work_own(p))) return -1;
    w->cancel = flag;
    work_drop_if_idle(p);
    return 0;
}

uint64_t frep_program_work_limit(const frep_program *p)
{
    return p && p->work && p->work->limit != PROG_NO_LIMIT ? p->work->limit : 0;
}

uint64_t frep_program_work_used(const frep_program *p)
{
    return p && p->work ? atomic_load_explicit(&p->work->used, memory_order_relaxed) : 0;
}

int frep_program_work_spent(const frep_program *p)
{
    return p && prog_work_spent(p->work);
}

/* ---- queries ------------------------------------------------------------------ */

size_t frep_program_size(const frep_program *p) { return p->ncode; }
size_t frep_program_nparams(const frep_program *p) { return p->nparams; }

size_t frep_program_na(const frep_program *p) { return p->na; }
size_t frep_program_nfree(const frep_program *p) { return p->nparams - p->na; }

/* Identifiers compare case-insensitively (ASCII), as the front end's. */
static int name_eq(const char *a, const char *b)
{
    for (; *a && *b; a++, b++) {
        char x = *a >= 'A' && *a <= 'Z' ? (char)(*a - 'A' + 'a') : *a;
        char y = *b >= 'A' && *b <= 'Z' ? (char)(*b - 'A' + 'a') : *b;
        if (x != y) return 0;
    }
    return *a == *b;
}

/* "a[K]" with 1 <= K <= na: index K - 1. */
static int a_index(const frep_program *p, const char *name, size_t *index)
{
    if ((name[0] != 'a' && name[0] != 'A') || name[1] != '[' || name[2] < '1' || name[2] > '9')
        return -1;
    char *end;
    unsigned long k = strtoul(name + 2, &end, 10);
    if (end[0] != ']' || end[1] != 0 || k > p->na) return -1;
    *index = (size_t)k - 1;
    return 0;
}

int frep_program_param_index(const frep_program *p, const char *name, size_t *index)
{
    if (!p || !name || !index) return -1;
    if (a_index(p, name, index) == 0) return 0;
    for (size_t i = p->na; i < p->nparams && p->params; i++)
        if (p->params[i].name && name_eq(p->params[i].name, name)) {
            *index = i;
            return 0;
        }
    return -1;
}

int frep_program_param_values(const frep_program *p, double *v, size_t n)
{
    if (!p || n < p->nparams || (p->nparams && !v)) return -1;
    for (size_t i = 0; i < p->nparams; i++) v[i] = p->params ? p->params[i].value : 0.0;
    return 0;
}

const char *frep_program_param_name(const frep_program *p, size_t i)
{
    return i < p->nparams && p->params ? p->params[i].name : NULL;
}

double frep_program_param_value(const frep_program *p, size_t i)
{
    return i < p->nparams && p->params ? p->params[i].value : NAN;
}

int frep_program_param_used(const frep_program *p, size_t i)
{
    if (!p || i >= p->nparams) return 0;
    for (uint32_t k = 0; k < p->ncode; k++)
        if (p->code[k].op == FREP_OP_PARAM && p->code[k].arg == i) return 1;
    return 0;
}

int frep_program_param_bounds(const frep_program *p, size_t i, double *lo, double *hi)
{
    if (i >= p->nparams || !p->params) return 0;
    if (lo) *lo = p->params[i].lo;
    if (hi) *hi = p->params[i].hi;
    return p->params[i].has_bounds != 0;
}

int frep_program_box(const frep_program *p, double box[6])
{
    if (!p->has_box) return 0;
    memcpy(box, p->box, sizeof p->box);
    return 1;
}

/* ---- disassembly ---------------------------------------------------------------- */

static const char *axis_name(uint32_t a) { return a == 0 ? "x" : a == 1 ? "y" : "z"; }

/* Operand text of one instruction, chosen by the op's fields (see ops.h). */
static void dis_operands(frep_buf *b, const frep_program *p, const frep_insn *in)
{
    /* A switch over unsigned: ops without operand fields share the default. */
    switch ((unsigned)in->op) {
    case FREP_OP_CONST: buf_printf(b, "%.17g", in->k); break;
    case FREP_OP_X: buf_printf(b, "%s", axis_name(in->arg)); break;
    case FREP_OP_PARAM:
        buf_printf(b, "%u", in->arg);
        if (p->params && in->arg < p->nparams && p->params[in->arg].name)
            buf_printf(b, " (%s)", p->params[in->arg].name);
        break;
    case FREP_OP_LOAD: case FREP_OP_STORE: buf_printf(b, "s%u", in->arg); break;
    case FREP_OP_PRIM: buf_printf(b, "p%u", in->arg); break;
    case FREP_OP_JMP: case FREP_OP_JZ: buf_printf(b, "-> %u", in->arg); break;
    case FREP_OP_LOADI: case FREP_OP_STOREI:
        buf_printf(b, "s%u[%.17g]", in->arg, in->k);
        break;
    case FREP_OP_AUNI: case FREP_OP_AINT: buf_printf(b, "alpha=%.17g", in->k); break;
    default:
        if (in->flags & INSN_KB) buf_printf(b, "b=%.17g", in->k);
        else if (in->flags & INSN_KA) buf_printf(b, "a=%.17g", in->k);
        break;
    }
    if (in->flags & INSN_QUIET)
        buf_printf(b, "%squiet", b->s && b->len && b->s[b->len - 1] != ' ' ? " " : "");
}

char *frep_disassemble(const frep_program *p)
{
    frep_buf b = FREP_BUF_INIT;
    uint32_t pc, i;
    buf_printf(&b, "; model %s", p->model ? p->model : "(unnamed)");
    if (p->file) buf_printf(&b, " from %s", p->file);
    buf_printf(&b, "\n; %u instructions, %u slots, stack %u, %u parameters", p->ncode,
               p->nslots, p->max_stack, p->nparams);
    if (p->nprims) buf_printf(&b, ", %u primitives", p->nprims);
    buf_printf(&b, "\n");
    for (i = 0; i < p->nparams && p->params; i++) {
        const frep_param_info *q = &p->params[i];
        buf_printf(&b, "; param %u %s = %.17g", i, q->name ? q->name : "?", q->value);
        if (q->has_bounds) buf_printf(&b, " in [%.17g, %.17g]", q->lo, q->hi);
        buf_printf(&b, "\n");
    }
    for (pc = 0; pc < p->ncode; pc++) {
        const frep_insn *in = &p->code[pc];
        size_t start;
        buf_printf(&b, "%6u  %-7s ", pc, op_name((frep_opcode)in->op));
        start = b.len;
        dis_operands(&b, p, in);
        if (p->pos && p->pos[pc].line) {
            size_t w = b.len - start;
            buf_printf(&b, "%*s; %u:%u", w < 24 ? (int)(24 - w) : 1, "", p->pos[pc].line,
                       p->pos[pc].col);
        }
        /* Trim the padding of operand-less lines. */
        while (!b.failed && b.len > 0 && b.s[b.len - 1] == ' ') b.len--;
        buf_printf(&b, "\n");
    }
    return buf_finish(&b, NULL);
}
