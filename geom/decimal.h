/* decimal.h - exact conversion of short decimal numbers, the fast path of the cloud
 * readers (geom/cloud.c) before strtod.
 */
#ifndef FREP_DECIMAL_H
#define FREP_DECIMAL_H

/* Most significant digits a number may have for the fast paths: 19 digits always fit
 * in 64 bits (10^19 - 1 < 2^64). */
#define DECIMAL_MAX_DIGITS 19

/* The decimal number that is exactly [s, end), [+-]digits[.digits][(e|E)[+-]digits],
 * into *v, rounded to nearest as strtod rounds it in the "C" locale; returns 1. Returns
 * 0, *v untouched, for anything it does not convert exactly (other forms, hex, inf,
 * nan, more than DECIMAL_MAX_DIGITS significant digits, a power of ten past the exact
 * ones, a result next to a rounding tie): the caller then asks strtod, which gives the
 * same bits wherever this returns 1. */
int decimal_parse(const char *s, const char *end, double *v);

#endif
