/* lex.re - re2c lexer of HyperFun 2.x source (tokens for lang/parse.y).
 *
 * Pipeline: source text -> this lexer -> lang/parse.y -> lang/ast.h tree.
 * Reentrant: all state is in lex_state (lang/lex.h).  It also collects `-- @word`
 * annotations, tracks open brackets and blocks for the parser's messages, and stops
 * nesting beyond FREP_MAX_NESTING before the parser stack can grow without bound.
 */
#include "config.h"

#include "lex.h"

#include <ctype.h>
#include <errno.h>
#include <locale.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Longest number literal converted; longer ones are kept exact only to this many
 * characters (far more than the 17 significant digits a double holds). */
#define LEX_MAX_NUMBER 400

void lex_error(lex_state *L, ast_loc loc, uint32_t len, const char *fmt, ...)
{
    if (L->error) return;
    L->error = 1;
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    diag_report(L->d, FREP_ERROR, loc, len, "%s", msg);
}

int lex_init(lex_state *L, arena *A, diag_sink *d, const char *filename, const char *src,
             size_t len)
{
    memset(L, 0, sizeof *L);
    L->A = A;
    L->d = d;
    L->filename = filename;
    L->line = 1;
    if (len > FREP_MAX_SOURCE) {
        lex_error(L, (ast_loc){ 0, 0, 0, 0 }, 0, "file too large (%zu bytes; at most %u)",
                  len, FREP_MAX_SOURCE);
        return -1;
    }
    /* A NUL-terminated copy: the NUL is re2c's end sentinel. */
    char *copy = arena_strndup(A, src ? src : "", src ? len : 0);
    if (!copy) {
        lex_error(L, (ast_loc){ 0, 0, 0, 0 }, 0, "out of memory");
        return -1;
    }
    L->src = copy;
    L->len = src ? len : 0;
    L->cur = L->line_start = copy;
    return 0;
}

static ast_loc here(const lex_state *L)
{
    ast_loc l;
    l.line = L->line;
    l.col = (uint32_t)(L->tok - L->line_start) + 1;
    l.off = (uint32_t)(L->tok - L->src);
    l.end = (uint32_t)(L->cur - L->src);
    return l;
}

/* Lower-case ASCII copy: identifiers are case-insensitive, compared by this key. */
static char *lower_copy(arena *A, const char *s, size_t n)
{
    char *k = arena_strndup(A, s, n);
    if (k)
        for (size_t i = 0; i < n; i++) k[i] = (char)tolower((unsigned char)k[i]);
    return k;
}

static int add_pragma(lex_state *L, const char *at, const char *word_end)
{
    ast_loc loc;
    loc.line = L->line;
    loc.col = (uint32_t)(at - L->line_start) + 1;
    loc.off = (uint32_t)(at - L->src);
    loc.end = (uint32_t)(L->cur - L->src);
    const char *t = word_end, *e = L->cur;
    while (t < e && (*t == ' ' || *t == '\t')) t++;
    while (e > t && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\r')) e--;
    if (L->npragmas == L->cap_pragmas) {
        uint32_t cap = L->cap_pragmas ? 2 * L->cap_pragmas : 8;
        ast_pragma *p = arena_grow(L->A, L->pragmas, L->npragmas, cap, sizeof *p);
        if (!p) return -1;
        L->pragmas = p;
        L->cap_pragmas = cap;
    }
    ast_pragma *p = &L->pragmas[L->npragmas];
    p->word = lower_copy(L->A, at + 1, (size_t)(word_end - at - 1));
    p->text = arena_strndup(L->A, t, (size_t)(e - t));
    p->loc = loc;
    if (!p->word || !p->text) return -1;
    L->npragmas++;
    return 0;
}

/* strtod in the "C" notation whatever the process locale: the decimal point of the
 * locale replaces '.' in a copy. */
static double to_double(const char *s, size_t n, int *range)
{
    char buf[LEX_MAX_NUMBER + 8];
    if (n > LEX_MAX_NUMBER) n = LEX_MAX_NUMBER;
    const char *dp = localeconv()->decimal_point;
    char point = dp && dp[0] ? dp[0] : '.';
    for (size_t i = 0; i < n; i++) buf[i] = s[i] == '.' ? point : s[i];
    buf[n] = '\0';
    errno = 0;
    double v = strtod(buf, NULL);
    *range = isinf(v);
    return v;
}

/* "invalid character" message for the byte(s) at tok. */
static void bad_char(lex_state *L, ast_loc loc)
{
    unsigned char c = (unsigned char)*L->tok;
    if (c == '"')
        lex_error(L, loc, 1, "string constants are not supported (HyperFun uses them "
                  "only in attribute functions)");
    else if (c >= 0x20 && c < 0x7f)
        lex_error(L, loc, 1, "invalid character '%c'", c);
    else if (c == 0)
        lex_error(L, loc, 1, "invalid character (a NUL byte)");
    else if (c >= 0xC2 && c <= 0xF4) {
        /* show a whole UTF-8 sequence as the character it is */
        size_t n = c >= 0xF0 ? 4 : c >= 0xE0 ? 3 : 2, k = 1;
        while (k < n && ((unsigned char)L->tok[k] & 0xC0) == 0x80) k++;
        if (k == n)
            lex_error(L, loc, 1, "invalid character '%.*s'", (int)n, L->tok);
        else
            lex_error(L, loc, 1, "invalid byte 0x%02x (not UTF-8 text)", c);
    } else
        lex_error(L, loc, 1, "invalid %s 0x%02x", c < 0x80 ? "control character" : "byte",
                  c);
}

/* Nesting bookkeeping for each token handed to the parser (see lex.h). Returns -1
 * after reporting "nested too deeply". */
static int track(lex_state *L, int tok, ast_loc loc)
{
    int opener = 0, closer = 0;
    switch (tok) {
    case T_LPAREN: opener = '('; break;
    case T_LBRACK: opener = '['; break;
    case T_LBRACE: opener = '{'; break;
    case T_IF: opener = 'i'; break;
    case T_WHILE: opener = 'w'; break;
    case T_RPAREN: closer = '('; break;
    case T_RBRACK: closer = '['; break;
    case T_RBRACE: closer = '{'; break;
    case T_ENDIF: closer = 'i'; break;
    case T_ENDLOOP: closer = 'w'; break;
    case T_ARRAY: L->in_decl = 1; break;
    case T_SEMI: L->in_decl = 0; break;
    default: break;
    }
    int prefix = tok == T_NOT || ((tok == T_MINUS || tok == T_PLUS || tok == T_TILDE) &&
                                  !L->last_ends_operand);
    L->unary_run = prefix ? L->unary_run + 1 : 0;
    if (closer && L->nopen && L->open[L->nopen - 1].kind == closer) L->nopen--;
    if (opener || prefix) {
        if (L->nopen + L->unary_run + (opener != 0) > FREP_MAX_NESTING) {
            lex_error(L, loc, loc.end - loc.off, "nested too deeply (more than %u levels "
                      "of brackets, blocks and prefix operators)", FREP_MAX_NESTING);
            return -1;
        }
        if (opener) {
            L->open[L->nopen].kind = opener;
            L->open[L->nopen].loc = loc;
            L->nopen++;
        }
    }
    L->last_ends_operand = tok == T_IDENT || tok == T_NUM || tok == T_RPAREN ||
                           tok == T_RBRACK;
    L->prev_tok = L->last_tok;
    L->prev_loc = L->last_loc;
    L->last_tok = tok;
    L->last_loc = loc;
    return 0;
}

static int scan(lex_state *L, FREP_YYSTYPE *val)
{
    for (;;) {
        const char *at, *wend; /* the '@' of an annotation and the end of its word */
        L->tok = L->cur;
        /*!stags:re2c format = 'const char *@@;\n'; */
        /*!re2c
        re2c:define:YYCTYPE = "unsigned char";
        re2c:define:YYCURSOR = "L->cur";
        re2c:define:YYMARKER = "L->mrk";
        re2c:yyfill:enable = 0;
        re2c:flags:tags = 1;

        digits = [0-9]+;
        exponent = [eE] [+-]? digits;
        number = digits ("." [0-9]*)? exponent? | "." digits exponent?;
        badnumber = (digits | "." digits?) ([a-zA-Z0-9_.] | [eE] [+-])*;
        ident = [a-zA-Z_] [a-zA-Z0-9_]*;

        "\x00" {
            if ((size_t)(L->tok - L->src) >= L->len) return FREP_YYEOF;
            L->cur = L->tok + 1;
            bad_char(L, here(L));
            return FREP_YYerror;
        }
        [ \t\r]+ { continue; }
        "\n" { L->line++; L->line_start = L->cur; continue; }
        "--" [ \t]* @at "@" [a-zA-Z_] [a-zA-Z0-9_]* @wend [^\n\x00]* {
            /* an annotation: the tags mark the '@' and the end of its word */
            if (add_pragma(L, at, wend)) {
                lex_error(L, here(L), 1, "out of memory");
                return FREP_YYerror;
            }
            continue;
        }
        "--" [^\n\x00]* { continue; }

        'array'   { return T_ARRAY; }
        'if'      { return T_IF; }
        'then'    { return T_THEN; }
        'else'    { return T_ELSE; }
        'endif'   { return T_ENDIF; }
        'while'   { return T_WHILE; }
        'loop'    { return T_LOOP; }
        'endloop' { return T_ENDLOOP; }
        'and'     { return T_AND; }
        'or'      { return T_OR; }
        'not'     { return T_NOT; }

        number {
            int range;
            val->num = to_double(L->tok, (size_t)(L->cur - L->tok), &range);
            if (range) {
                ast_loc l = here(L);
                lex_error(L, l, l.end - l.off, "number out of range '%.*s'",
                          (int)(l.end - l.off > 40 ? 40 : l.end - l.off), L->tok);
                return FREP_YYerror;
            }
            return T_NUM;
        }
        badnumber {
            ast_loc l = here(L);
            lex_error(L, l, l.end - l.off, "malformed number '%.*s'",
                      (int)(l.end - l.off > 40 ? 40 : l.end - l.off), L->tok);
            return FREP_YYerror;
        }
        ident {
            size_t n = (size_t)(L->cur - L->tok);
            if (n > FREP_MAX_IDENT) {
                ast_loc l = here(L);
                lex_error(L, l, l.end - l.off, "name too long (%zu characters; at most %u)",
                          n, FREP_MAX_IDENT);
                return FREP_YYerror;
            }
            val->id.name = arena_strndup(L->A, L->tok, n);
            val->id.key = lower_copy(L->A, L->tok, n);
            if (!val->id.name || !val->id.key) {
                lex_error(L, here(L), 1, "out of memory");
                return FREP_YYerror;
            }
            return T_IDENT;
        }

        "+"  { return T_PLUS; }
        "-"  { return T_MINUS; }
        "*"  { return T_STAR; }
        "/"  { return T_SLASH; }
        "^"  { return T_CARET; }
        "|"  { return T_BAR; }
        "&"  { return T_AMP; }
        "\\" { return T_BSLASH; }
        "@"  { return T_AT; }
        "~"  { return T_TILDE; }
        "="  { return T_EQ; }
        "/=" { return T_NE; }
        "<"  { return T_LT; }
        "<=" { return T_LE; }
        ">"  { return T_GT; }
        ">=" { return T_GE; }
        "("  { return T_LPAREN; }
        ")"  { return T_RPAREN; }
        "["  { return T_LBRACK; }
        "]"  { return T_RBRACK; }
        "{"  { return T_LBRACE; }
        "}"  { return T_RBRACE; }
        ","  { return T_COMMA; }
        ";"  { return T_SEMI; }

        [\xC2-\xF4] [\x80-\xBF]* {
            /* a whole (possibly broken) UTF-8 sequence is one bad character */
            bad_char(L, here(L));
            return FREP_YYerror;
        }
        * {
            bad_char(L, here(L));
            return FREP_YYerror;
        }
        */
    }
}

int frep_yylex(FREP_YYSTYPE *val, FREP_YYLTYPE *loc, lex_state *L)
{
    if (L->error) return FREP_YYerror;
    int tok = scan(L, val);
    if (tok == FREP_YYEOF) {
        L->tok = L->cur = L->src + L->len;
    }
    *loc = here(L);
    if (tok == FREP_YYerror) return tok;
    if (track(L, tok, *loc)) return FREP_YYerror;
    return tok;
}
