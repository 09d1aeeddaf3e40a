%define api.pure full
%define api.prefix {frep_yy}
%expect 0
%code {
static int frep_yylex(FREP_YYSTYPE *v) { (void)v; return 0; }
static void frep_yyerror(const char *m) { (void)m; }
}
%%
file: %empty ;
%%
