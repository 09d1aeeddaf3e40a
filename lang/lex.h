/* lex.h - placeholder; replaced by the front end. */
#ifndef FREP_LEX_H
#define FREP_LEX_H
int lex_placeholder(void);
#endif
