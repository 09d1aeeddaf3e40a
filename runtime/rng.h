/* rng.h - the pseudo-random generator of frep: xoshiro256** seeded through splitmix64.
 * Used by sampling, RANSAC, annealing and genetic programming. State belongs to its
 * user (no global generator), and a 64-bit seed gives the same stream on every
 * platform, so a seeded command gives the same result at any thread count.
 */
#ifndef FREP_RNG_H
#define FREP_RNG_H

#include <math.h>
#include <stdint.h>

#include "util.h"

typedef struct frep_rng {
    uint64_t s[4];
} frep_rng;

static inline uint64_t frep_splitmix64(uint64_t *x)
{
    uint64_t z = (*x += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static inline void frep_rng_seed(frep_rng *r, uint64_t seed)
{
    for (int i = 0; i < 4; i++) r->s[i] = frep_splitmix64(&seed);
}

static inline uint64_t frep_rng_rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

static inline uint64_t frep_rng_next(frep_rng *r)
{
    uint64_t *s = r->s;
    uint64_t res = frep_rng_rotl(s[1] * 5, 7) * 9, t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = frep_rng_rotl(s[3], 45);
    return res;
}

/* Uniform in [0, 1) with 53 random bits. */
static inline double frep_rng_unit(frep_rng *r)
{
    return (double)(frep_rng_next(r) >> 11) * 0x1.0p-53;
}

/* A standard normal deviate (Box-Muller, the cosine one of the pair): two uniform
 * draws, u first; 1 - u lies in (0, 1], so the logarithm is finite. */
static inline double frep_rng_normal(frep_rng *r)
{
    double u = 1.0 - frep_rng_unit(r), v = frep_rng_unit(r);
    return sqrt(-2.0 * log(u)) * cos(2.0 * FREP_PI * v);
}

#endif
