/* lex.re - placeholder */
#include "lex.h"
int lex_placeholder(void) { return 0; }
