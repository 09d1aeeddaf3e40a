/* print.c - canonical source of a parsed file (frep print).
 *
 * Pipeline: lang/parse.y tree -> this printer -> text that parses to the same tree.
 * Layout: two-space indentation, one statement a line, minimal parentheses (plus
 * those that keep mixed set/arithmetic or and/or chains explicit, and around the
 * operand of 'not'), numbers in the shortest %.17g-exact form, keywords in lower
 * case, names as written.  Annotations (-- @word text) stay in order: at the end
 * of the line of the construct they followed, or on a line of their own.
 */
#include "alloc.h"
#include "ast.h"
#include "buf.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct printer {
    frep_buf out;
    const ast_file *f;
    uint32_t next_pragma;   /* first annotation not printed yet */
    uint32_t line_end_line; /* source line where the current output line's construct
                               ends (0: no line open) */
    int indent;             /* of the current block, in levels */
} printer;

static void puts_(printer *p, const char *s) { buf_puts(&p->out, s); }

static void pad(printer *p, int levels)
{
    for (int i = 0; i < levels; i++) puts_(p, "  ");
}

static void put_pragma(printer *p, const ast_pragma *g)
{
    puts_(p, "-- @");
    puts_(p, g->word);
    if (g->text[0]) {
        puts_(p, " ");
        puts_(p, g->text);
    }
}

/* Annotations before source offset `off` written on the source line where the open
 * output line's construct ends: they go at the end of that output line. */
static void flush_trailing(printer *p, uint32_t off)
{
    const ast_file *f = p->f;
    while (p->line_end_line && p->next_pragma < f->npragmas &&
           f->pragmas[p->next_pragma].loc.off < off &&
           f->pragmas[p->next_pragma].loc.line == p->line_end_line) {
        puts_(p, " ");
        put_pragma(p, &f->pragmas[p->next_pragma++]);
    }
}

/* Before a construct starting at source offset `off`: end the open line, with the
 * annotations written on the same source line after it, then put the annotations
 * that stood on lines of their own before the construct. */
static void flush(printer *p, uint32_t off)
{
    const ast_file *f = p->f;
    flush_trailing(p, off);
    while (p->next_pragma < f->npragmas && f->pragmas[p->next_pragma].loc.off < off) {
        const ast_pragma *g = &f->pragmas[p->next_pragma++];
        if (p->line_end_line && g->loc.line == p->line_end_line) {
            puts_(p, " ");
            put_pragma(p, g);
        } else {
            if (p->line_end_line) puts_(p, "\n");
            p->line_end_line = 0;
            pad(p, p->indent);
            put_pragma(p, g);
            /* another annotation on this source line belongs after this one */
            p->line_end_line = g->loc.line;
        }
    }
    if (p->line_end_line) puts_(p, "\n");
    p->line_end_line = 0;
}

/* Start an output line for a construct beginning at `off`. */
static void begin_line(printer *p, uint32_t off)
{
    flush(p, off);
    pad(p, p->indent);
}

/* End the current output line's text; `end_line` is the source line where the
 * construct ends (annotations on it follow on this output line). */
static void end_line(printer *p, uint32_t end_line) { p->line_end_line = end_line; }

/* The exponent of a %g number without leading zeros ("2.5e-08" -> "2.5e-8"): the
 * reference interpreter's scanner (int_scanner.c of HyperFun) rejects an exponent
 * that starts with 0.  The mantissa needs no change: %g never writes a leading zero
 * before another digit ("0.5", never "05"), which that scanner rejects too. */
static void strip_exponent_zeros(char *buf)
{
    char *e = strchr(buf, 'e'), *d, *z;
    if (!e) return;
    d = e + 1;
    if (*d == '+' || *d == '-') d++;
    for (z = d; z[0] == '0' && z[1] != '\0'; z++) {}
    memmove(d, z, strlen(z) + 1);
}

/* Shortest of %.15g, %.16g, %.17g that reads back as the same double, in a form
 * the reference interpreter reads too. */
static void put_num(printer *p, double v)
{
    char buf[40];
    for (int prec = 15; prec <= 17; prec++) {
        snprintf(buf, sizeof buf, "%.*g", prec, v);
        if (strtod(buf, NULL) == v) break;
    }
    /* strtod and snprintf agree on the locale's decimal point; source needs '.' */
    for (char *c = buf; *c; c++)
        if (*c == ',') *c = '.';
    strip_exponent_zeros(buf);
    puts_(p, buf);
}

/* Precedence levels, lowest first (doc/language.md has the table). */
enum { P_LOGIC = 1, P_NOT, P_CMP, P_ADD, P_MUL, P_POW, P_UNARY, P_PRIMARY };

static int prec(const ast_node *e)
{
    switch (e->kind) {
    case AST_UNARY: return e->op == AST_OP_NOT ? P_NOT : P_UNARY;
    case AST_BINARY:
        switch (e->op) {
        case AST_OP_AND: case AST_OP_OR: return P_LOGIC;
        case AST_OP_EQ: case AST_OP_NE: case AST_OP_LT: case AST_OP_LE:
        case AST_OP_GT: case AST_OP_GE: return P_CMP;
        case '*': case '/': return P_MUL;
        case '^': return P_POW;
        default: return P_ADD;
        }
    case AST_NUM: case AST_VAR: case AST_INDEX: case AST_CALL:
    case AST_ASSIGN: case AST_ASSIGN_INDEX: case AST_ASSIGN_ARRAY: case AST_IF:
    case AST_WHILE:
        return P_PRIMARY;
    }
    return P_PRIMARY;
}

static int is_setop(int op) { return op == '|' || op == '&' || op == '\\' || op == '@'; }

static void expr(printer *p, const ast_node *e);

static void sub(printer *p, const ast_node *e, int parens)
{
    if (parens) puts_(p, "(");
    expr(p, e);
    if (parens) puts_(p, ")");
}

static void list(printer *p, const ast_list *l)
{
    for (uint32_t i = 0; i < l->n; i++) {
        if (i) puts_(p, ", ");
        expr(p, l->v[i]);
    }
}

static void expr(printer *p, const ast_node *e)
{
    switch (e->kind) {
    case AST_NUM: put_num(p, e->num); return;
    case AST_VAR: puts_(p, e->name); return;
    case AST_INDEX:
        puts_(p, e->name);
        puts_(p, "[");
        expr(p, e->a);
        puts_(p, "]");
        return;
    case AST_CALL:
        puts_(p, e->name);
        puts_(p, "(");
        list(p, &e->list);
        puts_(p, ")");
        return;
    case AST_UNARY:
        if (e->op == AST_OP_NOT) {
            puts_(p, "not ");
            /* 'not (a > b)' reads unambiguously; the reference binds 'not' tighter */
            sub(p, e->a, e->a->kind == AST_BINARY || e->a->kind == AST_UNARY);
        } else {
            puts_(p, e->op == '-' ? "-" : "~");
            /* '- -a' must not become the comment '--a' */
            if (e->a->kind == AST_UNARY && e->a->op == '-' && prec(e->a) >= P_UNARY)
                puts_(p, " ");
            sub(p, e->a, prec(e->a) < P_UNARY);
        }
        return;
    case AST_BINARY: {
        int pe = prec(e);
        const ast_node *a = e->a, *b = e->b;
        /* Left operand at the same level: needed only to keep a mixed set/arithmetic
         * or and/or chain explicit (the parser warns about those without). */
        int lp = prec(a) < pe;
        if (prec(a) == pe && a->kind == AST_BINARY) {
            if (pe == P_ADD && is_setop(a->op) != is_setop(e->op)) lp = 1;
            if (pe == P_LOGIC && a->op != e->op) lp = 1;
        }
        sub(p, a, lp);
        if (e->op == '^') puts_(p, "^");
        else {
            puts_(p, " ");
            puts_(p, ast_op_name(e->op));
            puts_(p, " ");
        }
        /* every binary operator groups left to right: an equal right operand needs
         * its parentheses */
        sub(p, b, prec(b) <= pe);
        return;
    }
    case AST_ASSIGN: case AST_ASSIGN_INDEX: case AST_ASSIGN_ARRAY: case AST_IF:
    case AST_WHILE:
        return;
    }
}

/* Line of the byte at off: counted from a known
 * position before it. */
static uint32_t line_of(const ast_file *f, uint32_t off, uint32_t from_line,
                        uint32_t from_off)
{
    uint32_t line = from_line;
    for (uint32_t i = from_off; i < off && i < f->len; i++)
        if (f->src[i] == '\n') line++;
    return line;
}

static void stmts(printer *p, const ast_list *l);

/* if_stmt -> 'if' expr 'then' stmts ['else' stmts] 'endif;' */
static void if_stmt(printer *p, const ast_node *s)
{
    begin_line(p, s->loc.off);
    puts_(p, "if ");
    expr(p, s->a);
    puts_(p, " then");
    end_line(p, s->op_loc.line);
    p->indent++;
    stmts(p, &s->body);
    p->indent--;
    if (s->body2.n) {
        begin_line(p, s->else_loc.off);
        puts_(p, "else");
        end_line(p, s->else_loc.line);
        p->indent++;
        stmts(p, &s->body2);
        p->indent--;
    }
    begin_line(p, s->close_loc.off);
    puts_(p, "endif;");
    end_line(p, s->close_loc.line);
}

/* while_stmt -> 'while' expr 'loop' stmts 'endloop;' */
static void while_stmt(printer *p, const ast_node *s)
{
    begin_line(p, s->loc.off);
    puts_(p, "while ");
    expr(p, s->a);
    puts_(p, " loop");
    end_line(p, s->op_loc.line);
    p->indent++;
    stmts(p, &s->body);
    p->indent--;
    begin_line(p, s->close_loc.off);
    puts_(p, "endloop;");
    end_line(p, s->close_loc.line);
}

/* stmt -> assignment ';' | if_stmt | while_stmt, each on lines of its own */
static void stmt(printer *p, const ast_node *s)
{
    switch (s->kind) {
    case AST_ASSIGN:
        begin_line(p, s->loc.off);
        puts_(p, s->name);
        puts_(p, " = ");
        expr(p, s->a);
        puts_(p, ";");
        break;
    case AST_ASSIGN_INDEX:
        begin_line(p, s->loc.off);
        puts_(p, s->name);
        puts_(p, "[");
        expr(p, s->a);
        puts_(p, "] = ");
        expr(p, s->b);
        puts_(p, ";");
        break;
    case AST_ASSIGN_ARRAY:
        begin_line(p, s->loc.off);
        puts_(p, s->name);
        puts_(p, " = [");
        list(p, &s->list);
        puts_(p, "];");
        break;
    case AST_IF:
        if_stmt(p, s);
        return;
    case AST_WHILE:
        while_stmt(p, s);
        return;
    case AST_NUM: case AST_VAR: case AST_INDEX: case AST_CALL: case AST_UNARY:
    case AST_BINARY:
        return;
    }
    /* simple statements end on the line of their ';' (the end of their span) */
    end_line(p, line_of(p->f, s->loc.end ? s->loc.end - 1 : 0, s->loc.line, s->loc.off));
}

static void stmts(printer *p, const ast_list *l)
{
    for (uint32_t i = 0; i < l->n; i++) stmt(p, l->v[i]);
}

static void decl(printer *p, const ast_array_decl *d)
{
    char buf[16];
    puts_(p, d->name);
    snprintf(buf, sizeof buf, "[%u]", (unsigned)d->size);
    puts_(p, buf);
}

char *ast_print(const ast_file *f)
{
    printer p;
    memset(&p, 0, sizeof p);
    p.f = f;
    for (uint32_t i = 0; i < f->nmodels; i++) {
        const ast_model *m = &f->models[i];
        if (i) {
            /* a blank line between models; annotations on lines of their own before
             * a model stay with it */
            flush_trailing(&p, m->loc.off);
            if (p.line_end_line) puts_(&p, "\n");
            p.line_end_line = 0;
            puts_(&p, "\n");
        }
        begin_line(&p, m->loc.off);
        puts_(&p, m->name);
        puts_(&p, "(");
        for (uint32_t j = 0; j < m->nparams; j++) {
            if (j) puts_(&p, ", ");
            decl(&p, &m->params[j]);
        }
        puts_(&p, ") {");
        end_line(&p, m->open_loc.line);
        p.indent = 1;
        if (m->narrays) {
            begin_line(&p, m->arrays[0].loc.off);
            puts_(&p, "array ");
            for (uint32_t j = 0; j < m->narrays; j++) {
                if (j) puts_(&p, ", ");
                decl(&p, &m->arrays[j]);
            }
            puts_(&p, ";");
            end_line(&p, m->arrays[m->narrays - 1].loc.line);
        }
        stmts(&p, &m->body);
        p.indent = 0;
        begin_line(&p, m->end_loc.off);
        puts_(&p, "}");
        end_line(&p, m->end_loc.line);
    }
    flush(&p, UINT32_MAX);
    if (!p.out.s) return NULL; /* nothing printed */
    return buf_finish(&p.out, NULL);
}
