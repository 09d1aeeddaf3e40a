/* test_parse.c - unit tests of the front end: lexer, parser, tree, printer and
 * diagnostics (lang/lex.re, lang/parse.y, lang/ast.c, lang/print.c, lang/diag.c).
 * Each case is a snippet with the tree it must give (as an s-expression) or the exact
 * first diagnostic; every accepted snippet also goes through the print round trip.
 */
#include "config.h"

#include <stdlib.h>
#include <string.h>

#include "arena.h"
#include "ast.h"
#include "tap.h"

/* ---- harness ---------------------------------------------------------------- */

typedef struct capture {
    char text[16384];   /* all diagnostics, formatted as the frep command prints them */
    size_t n;
    const char *src;
    size_t len;
} capture;

static void sink(void *user, const frep_diag *d)
{
    capture *c = user;
    char *s = frep_diag_format(d, c->src, c->len);
    if (!s) return;
    size_t k = strlen(s);
    /* long source lines are cut: the messages are what the tests look at */
    if (c->n + k >= sizeof c->text) k = sizeof c->text - c->n - 1;
    memcpy(c->text + c->n, s, k);
    c->n += k;
    c->text[c->n] = '\0';
    free(s);
}

typedef struct parsed {
    arena A;
    ast_file f;
    capture cap;
    diag_sink ds;
    int status;
} parsed;

static parsed *parse_n(const char *src, size_t len)
{
    parsed *p = calloc(1, sizeof *p);
    arena_init(&p->A);
    p->cap.src = src;
    p->cap.len = len;
    p->ds.fn = sink;
    p->ds.user = &p->cap;
    p->ds.file = "t.hf";
    p->status = ast_parse(&p->A, "t.hf", src, len, &p->ds, &p->f);
    return p;
}

static parsed *parse(const char *src) { return parse_n(src, strlen(src)); }

static void done(parsed *p)
{
    arena_free(&p->A);
    free(p);
}

/* First line of the diagnostics, without the "t.hf:" prefix. */
static const char *first_diag(parsed *p, char *buf, size_t size)
{
    const char *s = p->cap.text;
    if (strncmp(s, "t.hf:", 5) == 0) s += 5;
    if (*s == ' ') s++;
    size_t k = strcspn(s, "\n");
    if (k >= size) k = size - 1;
    memcpy(buf, s, k);
    buf[k] = '\0';
    return buf;
}

/* ---- tree dump ------------------------------------------------------------------- */

typedef struct sbuf {
    char s[4096];
    size_t n;
} sbuf;

static void sput(sbuf *b, const char *s)
{
    size_t k = strlen(s);
    if (b->n + k < sizeof b->s) {
        memcpy(b->s + b->n, s, k + 1);
        b->n += k;
    }
}

static void dump(sbuf *b, const ast_node *e)
{
    char tmp[64];
    switch (e->kind) {
    case AST_NUM: snprintf(tmp, sizeof tmp, "%g", e->num); sput(b, tmp); break;
    case AST_VAR: sput(b, e->key); break;
    case AST_INDEX: sput(b, "(["); sput(b, e->key); sput(b, " "); dump(b, e->a); sput(b, ")"); break;
    case AST_CALL:
        sput(b, "(");
        sput(b, e->key);
        for (uint32_t i = 0; i < e->list.n; i++) { sput(b, " "); dump(b, e->list.v[i]); }
        sput(b, ")");
        break;
    case AST_UNARY: sput(b, "("); sput(b, ast_op_name(e->op)); sput(b, " "); dump(b, e->a); sput(b, ")"); break;
    case AST_BINARY:
        sput(b, "(");
        sput(b, ast_op_name(e->op));
        sput(b, " ");
        dump(b, e->a);
        sput(b, " ");
        dump(b, e->b);
        sput(b, ")");
        break;
    case AST_ASSIGN: sput(b, "(= "); sput(b, e->key); sput(b, " "); dump(b, e->a); sput(b, ")"); break;
    case AST_ASSIGN_INDEX:
        sput(b, "([]= "); sput(b, e->key); sput(b, " "); dump(b, e->a); sput(b, " "); dump(b, e->b);
        sput(b, ")");
        break;
    case AST_ASSIGN_ARRAY:
        sput(b, "(=[] ");
        sput(b, e->key);
        for (uint32_t i = 0; i < e->list.n; i++) { sput(b, " "); dump(b, e->list.v[i]); }
        sput(b, ")");
        break;
    case AST_IF: case AST_WHILE:
        sput(b, e->kind == AST_IF ? "(if " : "(while ");
        dump(b, e->a);
        sput(b, " {");
        for (uint32_t i = 0; i < e->body.n; i++) { sput(b, " "); dump(b, e->body.v[i]); }
        sput(b, " }");
        if (e->kind == AST_IF) {
            sput(b, " {");
            for (uint32_t i = 0; i < e->body2.n; i++) { sput(b, " "); dump(b, e->body2.v[i]); }
            sput(b, " }");
        }
        sput(b, ")");
        break;
    }
}

/* ---- round trip ------------------------------------------------------------------ */

/* print(parse(s)) parses again to an equal tree and prints identically. */
static void round_trip(const char *what, parsed *p)
{
    char *a = ast_print(&p->f);
    if (!ok(a != NULL, "%s: prints", what)) return;
    parsed *q = parse(a);
    int same = q->status == 0 && ast_file_equal(&p->f, &q->f);
    char *b = q->status == 0 ? ast_print(&q->f) : NULL;
    ok(same && b && strcmp(a, b) == 0, "%s: print round trip", what);
    if (!same || !b || strcmp(a, b) != 0) {
        diag("printed:\n%s", a);
        diag("diagnostics: %s", q->cap.text);
        if (b) diag("printed again:\n%s", b);
    }
    free(a);
    free(b);
    done(q);
}

/* Parse `r = EXPR;` in a model and compare the dump of the expression. */
static void expr_is(const char *e, const char *want)
{
    char src[1024];
    snprintf(src, sizeof src, "m(x[3], a[1]) {\n  r = %s;\n  m = r;\n}\n", e);
    parsed *p = parse(src);
    if (!ok(p->status == 0, "parses: %s", e)) {
        diag("%s", p->cap.text);
        done(p);
        return;
    }
    sbuf b = { { 0 }, 0 };
    dump(&b, p->f.models[0].body.v[0]->a);
    is_str(b.s, want, "tree of %s", e);
    round_trip(e, p);
    done(p);
}

/* Whole file accepted; the dump of its first model's statements is `want`
 * (NULL: not checked). No diagnostics at all. */
static void file_is(const char *what, const char *src, const char *want)
{
    parsed *p = parse(src);
    if (!ok(p->status == 0 && p->cap.n == 0, "accepted cleanly: %s", what)) {
        diag("%s", p->cap.text);
        done(p);
        return;
    }
    if (want) {
        sbuf b = { { 0 }, 0 };
        const ast_list *l = &p->f.models[0].body;
        for (uint32_t i = 0; i < l->n; i++) {
            if (i) sput(&b, " ");
            dump(&b, l->v[i]);
        }
        is_str(b.s, want, "statements of %s", what);
    }
    round_trip(what, p);
    done(p);
}

/* Rejected with exactly this first diagnostic ("line:col: error: message"). */
static void error_is(const char *src, const char *want)
{
    parsed *p = parse(src);
    char buf[512];
    ok(p->status == -1, "rejected: %s", want);
    is_str(first_diag(p, buf, sizeof buf), want, "message: %s", want);
    /* one error, no cascade */
    const char *s = p->cap.text;
    int n = 0;
    while ((s = strstr(s, ": error: ")) != NULL) { n++; s++; }
    is_int(n, 1, "exactly one error: %s", want);
    done(p);
}

#define M(body) "m(x[3], a[1]) {\n" body "\n}\n"

/* ---- cases --------------------------------------------------------------------- */

static void test_precedence(void)
{
    expr_is("a + b * c", "(+ a (* b c))");
    expr_is("a - b - c", "(- (- a b) c)");
    expr_is("a / b / c", "(/ (/ a b) c)");
    expr_is("a ^ b ^ c", "(^ (^ a b) c)");           /* left-assoc, as the reference */
    expr_is("-a^2", "(^ (- a) 2)");                  /* unary binds tighter than ^ */
    expr_is("-(a^2)", "(- (^ a 2))");
    expr_is("a ^ -b", "(^ a (- b))");
    expr_is("2^-a^2", "(^ (^ 2 (- a)) 2)");
    expr_is("a * b ^ c", "(* a (^ b c))");
    expr_is("a | b & c", "(& (| a b) c)");
    expr_is("a | b * c", "(| a (* b c))");
    expr_is("a \\ b @ c", "(@ (\\ a b) c)");
    expr_is("~a | b", "(| (~ a) b)");
    expr_is("~(a | b)", "(~ (| a b))");
    expr_is("- -a", "(- (- a))");
    expr_is("-(-a)", "(- (- a))");
    expr_is("+a * +2", "(* a 2)");
    expr_is("2 * -3", "(* 2 (- 3))");
    expr_is("a - (b - c)", "(- a (- b c))");
    expr_is("(a | b) + c", "(+ (| a b) c)");
    expr_is("a | (b + c)", "(| a (+ b c))");
    expr_is("hfSphere(x, c, 1.5) | hfBlock(x, 0, 0, 0, 1, 1, 1)",
            "(| (hfsphere x c 1.5) (hfblock x 0 0 0 1 1 1))");
    expr_is("c[i + 1] * x[1]", "(* ([c (+ i 1)) ([x 1))");
    expr_is("sqrt(x[1]^2 + x[2]^2)", "(sqrt (+ (^ ([x 1) 2) (^ ([x 2) 2)))");
    expr_is("f()", "(f)");
    expr_is(".5 + 1. + 1e-3 + 2.5E+3 + 007", "(+ (+ (+ (+ 0.5 1) 0.001) 2500) 7)");
    /* conditions: comparisons below arithmetic, 'not' applied to the next operand of
     * a comparison (HF_For_Bool in the reference's int_parse_N.c: 'not' then an
     * operand, a parenthesized condition or an arithmetic expression), and 'and'
     * and 'or' on one level, left to right, as in the reference */
    expr_is("a + 1 >= b - 1", "(>= (+ a 1) (- b 1))");
    expr_is("not a > b", "(> (not a) b)");
    expr_is("not (a > b)", "(not (> a b))");
    expr_is("not a + 1 > b", "(> (not (+ a 1)) b)");
    expr_is("not a > b and c < d", "(and (> (not a) b) (< c d))");
    expr_is("a = b or c /= d", "(or (= a b) (/= c d))");
    expr_is("a < b and (c <= d or e > f)", "(and (< a b) (or (<= c d) (> e f)))");
    expr_is("(a + b) * 2 > c", "(> (* (+ a b) 2) c)");
    expr_is("not not a = 1", "(= (not (not a)) 1)");
}

static void test_statements(void)
{
    file_is("array declarations and all statement kinds",
            "m(x[3], a[1]) {\n"
            "  array c[3], d[2];\n"
            "  array e[1];\n"
            "  c = [1, -2, 3.5];\n"
            "  d[1] = x[1];\n"
            "  i = 0;\n"
            "  while i < 3 loop i = i + 1; endloop;\n"
            "  if i = 3 then r = 1; else r = 2; endif;\n"
            "  if i > 0 then endif;\n"
            "  m = r;\n"
            "}\n",
            "(=[] c 1 (- 2) 3.5) ([]= d 1 ([x 1)) (= i 0) "
            "(while (< i 3) { (= i (+ i 1)) }) "
            "(if (= i 3) { (= r 1) } { (= r 2) }) (if (> i 0) { } { }) (= m r)");
    file_is("else if chains nest",
            M("if a[1] > 0 then r = 1; else if a[1] < 0 then r = -1; else r = 0; endif; endif;\n"
              "m = r;"),
            "(if (> ([a 1) 0) { (= r 1) } { (if (< ([a 1) 0) { (= r (- 1)) } { (= r 0) }) }) "
            "(= m r)");
    file_is("empty bodies", M("while 0 > 1 loop endloop; if 1 > 0 then else endif; m = 1;"),
            "(while (> 0 1) { }) (if (> 1 0) { } { }) (= m 1)");
    file_is("three parameter arrays",
            "m(x[3], a[2], s[4]) { s[1] = 1; m = x[1]; }", "([]= s 1 1) (= m ([x 1))");
    file_is("whole-array copy parses (the checker decides)", M("array c[3]; c = x; m = c[1];"),
            "(= c x) (= m ([c 1))");

    /* several models, calls between them */
    parsed *p = parse("a1(x[3], a[1]) { a1 = 1 - x[1]; }\n"
                      "-- a comment\n"
                      "my_model(x[3], a[1]) { my_model = a1(x, a) & 2; }\n");
    is_int(p->status, 0, "two models parse");
    is_int(p->f.nmodels, 2, "two models");
    is_str(p->f.models[1].name, "my_model", "second model's name");
    is_int(p->f.models[0].params[0].size, 3, "x[3]");
    round_trip("two models", p);
    done(p);
}

static void test_case_and_crlf(void)
{
    const char *lf = "M(X[3], A[1]) {\n  ARRAY C[2];\n  IF X[1] > 0 AND NOT X[2] < 0 THEN\n"
                     "    R = 1;\n  ELSE\n    R = 2;\n  ENDIF;\n  WHILE R < 3 LOOP R = R + 1; ENDLOOP;\n"
                     "  M = hfSphere(X, C, R);\n}\n";
    parsed *p = parse(lf);
    ok(p->status == 0 && p->cap.n == 0, "upper-case keywords are keywords");
    const ast_node *s = p->f.models[0].body.v[2];
    is_str(s->name, "M", "name kept as written");
    is_str(s->key, "m", "key lower-cased");
    is_str(s->a->name, "hfSphere", "call name as written");
    is_str(s->a->key, "hfsphere", "call key lower-cased");
    char *printed = ast_print(&p->f);
    ok(printed && strstr(printed, "if X[1] > 0 and (not X[2]) < 0 then") != NULL,
       "keywords printed in lower case, names as written");
    free(printed);

    /* the same file with CRLF line ends gives the same tree and positions */
    char crlf[1024];
    size_t n = 0;
    for (const char *c = lf; *c; c++) {
        if (*c == '\n') crlf[n++] = '\r';
        crlf[n++] = *c;
    }
    crlf[n] = '\0';
    parsed *q = parse(crlf);
    ok(q->status == 0 && q->cap.n == 0, "CRLF file accepted");
    ok(ast_file_equal(&p->f, &q->f), "CRLF gives the same tree");
    is_int(q->f.models[0].body.v[2]->loc.line, 9, "CRLF: line of the last statement");
    is_int(q->f.models[0].body.v[2]->loc.col, 3, "CRLF: column of the last statement");
    done(q);
    done(p);

    error_is("m(x[3], a[1]) {\r\n  m = 1 $ 2;\r\n}\r\n", "2:9: error: invalid character '$'");
    /* tabs are one column; the caret line reproduces them */
    p = parse("m(x[3], a[1]) {\n\tm = 1 +\t;\n}\n");
    is_str(p->cap.text,
           "t.hf:2:10: error: expected an expression, found ';'\n"
           "\tm = 1 +\t;\n"
           "\t       \t^\n",
           "tab in the caret line");
    done(p);
}

static void test_locations(void)
{
    parsed *p = parse("m(x[3], a[1]) {\n  r = -0.5; -- @free [-1, 1]\n  m = r +  -  2.25e1;\n}\n");
    ok(p->status == 0, "parses");
    const ast_node *r = p->f.models[0].body.v[0];
    is_int(r->loc.line, 2, "statement line");
    is_int(r->loc.col, 3, "statement col");
    const ast_node *neg = r->a;
    ok(neg->kind == AST_UNARY && neg->a->kind == AST_NUM, "negative number: unary over number");
    is_int(neg->loc.end - neg->loc.off, 4, "span covers the minus and the digits");
    ok(memcmp(p->f.src + neg->loc.off, "-0.5", 4) == 0, "bytes of the span");
    ok(memcmp(p->f.src + neg->a->loc.off, "0.5", 3) == 0, "number alone");
    is_double(neg->a->num, 0.5, 0, "value of the number");
    const ast_node *e = p->f.models[0].body.v[1]->a;
    ok(memcmp(p->f.src + e->b->loc.off, "-  2.25e1", e->b->loc.end - e->b->loc.off) == 0 &&
       e->b->loc.end - e->b->loc.off == 9, "span of '-  2.25e1'");
    is_int(e->op_loc.col, 9, "operator column");
    is_int(p->f.npragmas, 1, "one annotation");
    is_str(p->f.pragmas[0].word, "free", "word");
    is_str(p->f.pragmas[0].text, "[-1, 1]", "text trimmed");
    is_int(p->f.pragmas[0].loc.line, 2, "annotation line");
    is_int(p->f.pragmas[0].loc.col, 16, "annotation column (the '@')");
    done(p);
}

static void test_pragmas_print(void)
{
    const char *src =
        "-- @setops ralpha 0.5\n"
        "-- @box -1 -1 -1 1 1 1   \n"
        "m(x[3], a[1]) { -- @note on the header\n"
        "  -- plain comments are dropped\n"
        "  r = 0.5;   --  @FREE   [0.1, 1]\n"
        "  -- @standalone\n"
        "  if r > 0 then -- @after_then\n"
        "    q = r; -- @in_body\n"
        "  endif; -- @after_endif\n"
        "  m = q; -- @x one -- @y two\n"
        "} -- @end\n";
    parsed *p = parse(src);
    ok(p->status == 0 && p->cap.n == 0, "annotated file parses");
    is_int(p->f.npragmas, 10, "ten annotations");
    is_str(p->f.pragmas[2].word, "note", "word after the brace");
    is_str(p->f.pragmas[3].word, "free", "word lower-cased");
    is_str(p->f.pragmas[3].text, "[0.1, 1]", "text");
    is_str(p->f.pragmas[8].text, "one -- @y two", "rest of the line is the text");
    char *out = ast_print(&p->f);
    is_str(out ? out : "",
           "-- @setops ralpha 0.5\n"
           "-- @box -1 -1 -1 1 1 1\n"
           "m(x[3], a[1]) { -- @note on the header\n"
           "  r = 0.5; -- @free [0.1, 1]\n"
           "  -- @standalone\n"
           "  if r > 0 then -- @after_then\n"
           "    q = r; -- @in_body\n"
           "  endif; -- @after_endif\n"
           "  m = q; -- @x one -- @y two\n"
           "} -- @end\n",
           "annotations printed in place");
    free(out);
    round_trip("annotations", p);
    done(p);

    p = parse("a(x[3], a[1]) { a = 1; } -- @one\n\n-- @two\nb(x[3], a[1]) { b = 2; }\n");
    out = ast_print(&p->f);
    is_str(out ? out : "",
           "a(x[3], a[1]) {\n  a = 1;\n} -- @one\n\n-- @two\nb(x[3], a[1]) {\n  b = 2;\n}\n",
           "annotations between models: after the first, before the second");
    free(out);
    done(p);
}

static void test_errors(void)
{
    error_is("", "error: no model in the file: expected a model such as "
                 "'my_model(x[3], a[1]) { ... }'");
    error_is("-- only a comment\n", "error: no model in the file: expected a model such "
                                    "as 'my_model(x[3], a[1]) { ... }'");
    error_is("m(x[3], a[1]) {\n  f = (a[1] + 2;\n  m = f;\n}\n",
             "2:16: error: expected ')' to close '(' at 2:7");
    error_is(M("  f = 1\n  m = f;"), "2:8: error: expected ';' after assignment, found name 'm'");
    error_is(M("  endif;"), "2:3: error: unexpected 'endif' without a matching 'if'");
    error_is("m(x[3], a[1]) {\n  if a[1] > 0 then\n    m = 1;\n",
             "3:11: error: expected 'endif' to close 'if' at 2:3 (reached end of file)");
    error_is(M("  while a[1] > 0 loop m = 1;\n"),
             "4:1: error: expected 'endloop' to close 'while' at 2:3");
    error_is(M("  if a[1] > 0 m = 1; endif;"),
             "2:15: error: expected 'then' after the condition of 'if', found name 'm'");
    error_is(M("  if a[1] > 0 then m = 1; endif\n  m = 2;"),
             "2:32: error: expected ';' after 'endif'");
    error_is(M("  m = 1 +;"), "2:10: error: expected an expression, found ';'");
    error_is(M("  m = 1e;"), "2:7: error: malformed number '1e'");
    error_is(M("  m = 1.5.2;"), "2:7: error: malformed number '1.5.2'");
    error_is(M("  m = 2x;"), "2:7: error: malformed number '2x'");
    error_is(M("  m = 1e999;"), "2:7: error: number out of range '1e999'");
    error_is(M("  m = \"s\";"), "2:7: error: string constants are not supported (HyperFun "
                                "uses them only in attribute functions)");
    error_is(M("  m = 1; array c[2];"),
             "2:10: error: array declarations must come before the first statement of model 'm'");
    /* sizes are rounded as the reference's HF_round does: 0.4 -> 0 */
    error_is(M("  array c[0.4]; m = 1;"), "2:11: error: array size must be at least 1");
    error_is(M("  array c[0]; m = 1;"), "2:11: error: array size must be at least 1");
    error_is(M("  array c[3] d[2]; m = 1;"),
             "2:13: error: expected ',' or ';' in array declaration, found name 'd'");
    error_is("m(x[3]) { m = 1; }", "1:3: error: a model takes 2 or 3 arrays: name(x[3], a[1]) "
                                  "or name(x[3], a[1], s[1])");
    error_is("m(x[3], a[1], s[1], t[1]) { m = 1; }",
             "1:21: error: a model takes 2 or 3 arrays: name(x[3], a[1]) or name(x[3], a[1], s[1])");
    error_is("m(x[3], a[1]) m = 1;", "1:15: error: expected '{', found name 'm'");
    error_is("m(x[3], a[1]) { m = 1; }\n3", "2:1: error: expected a model such as "
                                            "'my_model(x[3], a[1]) { ... }', found number '3'");
    error_is(M("  m = f(1, 2;"), "2:13: error: expected ')' to close '(' at 2:8");
    error_is(M("  m = c[1;"), "2:10: error: expected ']' to close '[' at 2:8");
    error_is(M("  m = [1, 2;"), "2:12: error: expected ']' to close '[' at 2:7");
    error_is(M("  m = (1]);"), "2:9: error: expected ')' to close '(' at 2:7");
    error_is(M("  m = 1 \xc3\xa9;"), "2:9: error: invalid character '\xc3\xa9'");
    error_is("m(x[3], a[1]) {\n  m = 1;\n\x01}", "3:1: error: invalid control character 0x01");
    error_is(M("  3 = m;"), "2:3: error: expected a statement, 'array' or '}', found number '3'");
    error_is(M("  m == 1;"), "2:6: error: expected an expression or '[', found '='");
}

static void test_warnings(void)
{
    parsed *p = parse(M("  m = x[1] | x[2] + 1;"));
    ok(p->status == 0, "mixed set/arithmetic parses");
    is_str(p->cap.text,
           "t.hf:2:19: warning: '|' and '+' share one precedence level and group left to "
           "right: this is (... | ...) + ...; add parentheses to make the order explicit\n"
           "  m = x[1] | x[2] + 1;\n"
           "                  ^\n",
           "warning with caret");
    char *out = ast_print(&p->f);
    ok(out && strstr(out, "m = (x[1] | x[2]) + 1;") != NULL, "printer adds the parentheses");
    round_trip("mixed", p);
    free(out);
    done(p);

    p = parse(M("  m = (x[1] | x[2]) + 1 - x[3] & x[1];"));
    ok(p->status == 0 && strstr(p->cap.text, "'-' and '&'") != NULL &&
       strstr(p->cap.text, "'|' and '+'") == NULL, "parenthesized: no warning; unparenthesized: one");
    done(p);

    p = parse(M("  if x[1] > 0 or x[2] > 0 and x[3] > 0 then m = 1; else m = 2; endif;"));
    ok(p->status == 0 && strstr(p->cap.text, "warning: 'and' and 'or' share one precedence") != NULL,
       "and/or mixed: warning");
    done(p);

    p = parse(M("  m = x[1] - x[2] + x[3] | x[1] & x[2];"));
    is_int(p->ds.warnings, 1, "only the switch between classes warns");
    done(p);
}

static void test_limits(void)
{
    /* FREP_MAX_NESTING: brackets */
    size_t n = FREP_MAX_NESTING + 10;
    char *s = malloc(16 * n + 100);
    char *q = s + sprintf(s, "m(x[3], a[1]) { m = ");
    for (size_t i = 0; i < n; i++) *q++ = '(';
    *q++ = '1';
    for (size_t i = 0; i < n; i++) *q++ = ')';
    strcpy(q, "; }");
    parsed *p = parse(s);
    char buf[512];
    ok(p->status == -1 && strstr(first_diag(p, buf, sizeof buf), "nested too deeply") != NULL,
       "too many parentheses: nested too deeply");
    diag("%s", buf);
    done(p);
    /* exactly at the limit is fine: the model's '{' is one level */
    q = s + sprintf(s, "m(x[3], a[1]) { m = ");
    for (size_t i = 0; i + 1 < FREP_MAX_NESTING; i++) *q++ = '(';
    *q++ = '1';
    for (size_t i = 0; i + 1 < FREP_MAX_NESTING; i++) *q++ = ')';
    strcpy(q, "; }");
    p = parse(s);
    ok(p->status == 0, "nesting at the limit parses");
    round_trip("deep parentheses", p);
    done(p);
    /* prefix operators in a row */
    q = s + sprintf(s, "m(x[3], a[1]) { m = ");
    for (size_t i = 0; i < n; i++) { *q++ = '-'; *q++ = ' '; }
    strcpy(q, "1; }");
    p = parse(s);
    ok(p->status == -1 && strstr(first_diag(p, buf, sizeof buf), "nested too deeply") != NULL,
       "too many prefix minus: nested too deeply");
    done(p);
    /* nested if */
    q = s + sprintf(s, "m(x[3], a[1]) { ");
    for (size_t i = 0; i < n / 2; i++) q += sprintf(q, "if 1>0 then if 1>0 then ");
    sprintf(q, "m = 1;");
    p = parse(s);
    ok(p->status == -1 && strstr(first_diag(p, buf, sizeof buf), "nested too deeply") != NULL,
       "too many nested if: nested too deeply");
    done(p);
    free(s);

    /* FREP_MAX_EXPR_DEPTH: a long chain a+a+...; at the limit it parses */
    size_t terms = FREP_MAX_EXPR_DEPTH + 5;
    s = malloc(4 * terms + 100);
    q = s + sprintf(s, "m(x[3], a[1]) { m = 1");
    for (size_t i = 1; i < terms; i++) { memcpy(q, "+1", 2); q += 2; }
    strcpy(q, "; }");
    p = parse(s);
    ok(p->status == -1 && strstr(first_diag(p, buf, sizeof buf), "nested too deeply (more than") != NULL,
       "chain longer than FREP_MAX_EXPR_DEPTH rejected");
    diag("%s", buf);
    done(p);
    q = s + sprintf(s, "m(x[3], a[1]) { m = 1");
    for (size_t i = 1; i < FREP_MAX_EXPR_DEPTH; i++) { memcpy(q, "+1", 2); q += 2; }
    strcpy(q, "; }");
    p = parse(s);
    ok(p->status == 0, "chain of FREP_MAX_EXPR_DEPTH nodes parses");
    done(p);
    free(s);

    /* FREP_MAX_IDENT */
    s = malloc(FREP_MAX_IDENT + 100);
    q = s + sprintf(s, "m(x[3], a[1]) { ");
    memset(q, 'v', FREP_MAX_IDENT);
    strcpy(q + FREP_MAX_IDENT, " = 1; m = 1; }");
    p = parse(s);
    ok(p->status == 0, "name of FREP_MAX_IDENT characters");
    done(p);
    memset(q, 'v', FREP_MAX_IDENT + 1);
    strcpy(q + FREP_MAX_IDENT + 1, " = 1; m = 1; }");
    p = parse(s);
    snprintf(buf, sizeof buf, "1:17: error: name too long (%u characters; at most %u)",
             FREP_MAX_IDENT + 1, FREP_MAX_IDENT);
    char got[512];
    is_str(first_diag(p, got, sizeof got), buf, "name too long");
    done(p);
    free(s);

    /* FREP_MAX_ARRAY */
    char src[256];
    snprintf(src, sizeof src, M("  array c[%u]; m = 1;"), FREP_MAX_ARRAY);
    p = parse(src);
    ok(p->status == 0, "array of FREP_MAX_ARRAY elements");
    done(p);
    snprintf(src, sizeof src, M("  array c[%u]; m = 1;"), FREP_MAX_ARRAY + 1);
    snprintf(buf, sizeof buf, "2:11: error: array too large (at most %u elements)", FREP_MAX_ARRAY);
    error_is(src, buf);

    /* FREP_MAX_ARGS */
    s = malloc(3 * FREP_MAX_ARGS + 100);
    q = s + sprintf(s, "m(x[3], a[1]) { m = f(1");
    for (size_t i = 1; i <= FREP_MAX_ARGS; i++) { memcpy(q, ",1", 2); q += 2; }
    strcpy(q, "); }");
    p = parse(s);
    snprintf(buf, sizeof buf, "too many arguments in a call (at most %u)", FREP_MAX_ARGS);
    ok(p->status == -1 && strstr(p->cap.text, buf) != NULL, "too many arguments");
    done(p);
    free(s);

    /* FREP_MAX_MODELS */
    size_t per = 40;
    s = malloc(per * (FREP_MAX_MODELS + 2));
    q = s;
    for (size_t i = 0; i <= FREP_MAX_MODELS; i++) q += sprintf(q, "m%zu(x[3],a[1]){m%zu=1;}\n", i, i);
    p = parse(s);
    snprintf(buf, sizeof buf, "%u:1: error: too many models in one file (at most %u)",
             FREP_MAX_MODELS + 1, FREP_MAX_MODELS);
    is_str(first_diag(p, got, sizeof got), buf, "too many models");
    done(p);
    free(s);

    /* FREP_MAX_SOURCE */
    size_t big = (size_t)FREP_MAX_SOURCE + 1;
    s = malloc(big);
    if (s) {
        memset(s, ' ', big);
        p = parse_n(s, big);
        snprintf(buf, sizeof buf, "error: file too large (%zu bytes; at most %u)", big,
                 FREP_MAX_SOURCE);
        is_str(first_diag(p, got, sizeof got), buf, "file too large");
        done(p);
        free(s);
    }
}

static void test_diag_format(void)
{
    frep_diag d = { FREP_ERROR, "f.hf", 2, 5, 3, "bad thing" };
    const char *src = "line one\r\nab\tcdefg\nlast";
    char *s = frep_diag_format(&d, src, strlen(src));
    is_str(s, "f.hf:2:5: error: bad thing\nab\tcdefg\n  \t ^~~\n", "caret span after a tab, CRLF");
    free(s);
    d.line = 3; d.col = 5; d.len = 1; d.severity = FREP_WARNING;
    s = frep_diag_format(&d, src, strlen(src));
    is_str(s, "f.hf:3:5: warning: bad thing\nlast\n    ^\n", "caret after the end of the last line");
    free(s);
    d.line = 0; d.file = NULL; d.severity = FREP_NOTE;
    s = frep_diag_format(&d, src, strlen(src));
    is_str(s, "note: bad thing\n", "no position, no file");
    free(s);
    d.file = "f.hf"; d.line = 1; d.col = 1; d.len = 100; d.severity = FREP_ERROR;
    s = frep_diag_format(&d, NULL, 0);
    is_str(s, "f.hf:1:1: error: bad thing\n", "no source text");
    free(s);
}

int main(void)
{
    test_precedence();
    test_statements();
    test_case_and_crlf();
    test_locations();
    test_pragmas_print();
    test_errors();
    test_warnings();
    test_limits();
    test_diag_format();
    return done_testing();
}
