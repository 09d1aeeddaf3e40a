/* ast.c - construction and comparison of syntax trees (lang/ast.h).
 *
 * Pipeline: lang/parse.y builds trees with these constructors; lang/print.c prints
 * them; tests compare them with ast_file_equal for the print round trip.
 */
#include "ast.h"

#include <string.h>

int ast_list_push(arena *A, ast_list *l, ast_node *n)
{
    if (l->n == l->cap) {
        uint32_t cap = l->cap ? 2 * l->cap : 4;
        ast_node **v = arena_grow(A, l->v, l->n, cap, sizeof *v);
        if (!v) return -1;
        l->v = v;
        l->cap = cap;
    }
    l->v[l->n++] = n;
    return 0;
}

ast_node *ast_new(arena *A, ast_kind kind, ast_loc loc)
{
    ast_node *n = arena_alloc(A, sizeof *n);
    if (!n) return NULL;
    n->kind = kind;
    n->loc = loc;
    n->op_loc = loc;
    n->depth = 1;
    return n;
}

ast_node *ast_num(arena *A, ast_loc loc, double v)
{
    ast_node *n = ast_new(A, AST_NUM, loc);
    if (n) n->num = v;
    return n;
}

ast_node *ast_unary(arena *A, ast_loc loc, ast_loc op_loc, int op, ast_node *a)
{
    ast_node *n = ast_new(A, AST_UNARY, loc);
    if (!n) return NULL;
    n->op = op;
    n->op_loc = op_loc;
    n->a = a;
    n->depth = a->depth + 1;
    return n;
}

ast_node *ast_binary(arena *A, ast_loc loc, ast_loc op_loc, int op, ast_node *a,
                     ast_node *b)
{
    ast_node *n = ast_new(A, AST_BINARY, loc);
    if (!n) return NULL;
    n->op = op;
    n->op_loc = op_loc;
    n->a = a;
    n->b = b;
    n->depth = (a->depth > b->depth ? a->depth : b->depth) + 1;
    return n;
}

const char *ast_op_name(int op)
{
    switch (op) {
    case AST_OP_EQ: return "=";
    case AST_OP_NE: return "/=";
    case AST_OP_LT: return "<";
    case AST_OP_LE: return "<=";
    case AST_OP_GT: return ">";
    case AST_OP_GE: return ">=";
    case AST_OP_AND: return "and";
    case AST_OP_OR: return "or";
    case AST_OP_NOT: return "not";
    case '+': return "+";
    case '-': return "-";
    case '*': return "*";
    case '/': return "/";
    case '^': return "^";
    case '|': return "|";
    case '&': return "&";
    case '\\': return "\\";
    case '@': return "@";
    case '~': return "~";
    default: return "?";
    }
}

static int str_eq(const char *a, const char *b)
{
    if (!a || !b) return a == b;
    return strcmp(a, b) == 0;
}

static int list_equal(const ast_list *a, const ast_list *b)
{
    if (a->n != b->n) return 0;
    for (uint32_t i = 0; i < a->n; i++)
        if (!ast_node_equal(a->v[i], b->v[i])) return 0;
    return 1;
}

int ast_node_equal(const ast_node *a, const ast_node *b)
{
    if (!a || !b) return a == b;
    if (a->kind != b->kind || a->op != b->op || !str_eq(a->name, b->name)) return 0;
    /* Numbers compare by value; NaN never occurs (the lexer rejects overflow). */
    if (a->kind == AST_NUM && a->num != b->num) return 0;
    return ast_node_equal(a->a, b->a) && ast_node_equal(a->b, b->b) &&
           list_equal(&a->list, &b->list) && list_equal(&a->body, &b->body) &&
           list_equal(&a->body2, &b->body2);
}

static int decl_equal(const ast_array_decl *a, const ast_array_decl *b)
{
    return str_eq(a->name, b->name) && a->size == b->size;
}

int ast_file_equal(const ast_file *a, const ast_file *b)
{
    if (a->nmodels != b->nmodels || a->npragmas != b->npragmas) return 0;
    for (uint32_t i = 0; i < a->npragmas; i++)
        if (!str_eq(a->pragmas[i].word, b->pragmas[i].word) ||
            !str_eq(a->pragmas[i].text, b->pragmas[i].text))
            return 0;
    for (uint32_t i = 0; i < a->nmodels; i++) {
        const ast_model *m = &a->models[i], *n = &b->models[i];
        if (!str_eq(m->name, n->name) || m->nparams != n->nparams ||
            m->narrays != n->narrays)
            return 0;
        for (uint32_t j = 0; j < m->nparams; j++)
            if (!decl_equal(&m->params[j], &n->params[j])) return 0;
        for (uint32_t j = 0; j < m->narrays; j++)
            if (!decl_equal(&m->arrays[j], &n->arrays[j])) return 0;
        if (!list_equal(&m->body, &n->body)) return 0;
    }
    return 1;
}
