/* faults.c - the failing, counting allocator of tests/faults.h.
 *
 * Every block carries a header with its run (generation) and allocation number and
 * sits in a doubly linked list of live blocks, so a leak can be named. The links are
 * stored XOR-masked: LeakSanitizer then does not see the list as references, and
 * still reports a leaked block, with its stack, at exit.
 */
#include "config.h"

#include "faults.h"
#include "frep.h"

#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef __GLIBC__
#include <dlfcn.h>
#include <execinfo.h>
#endif

/* Frames kept of the failed allocation's stack. */
#define FAULT_FRAMES 24
/* Mask of the list links (any value that is not a plausible address). */
#define FAULT_LINK_MASK ((uintptr_t)0xa5a5a5a5a5a5a5a5ull)

typedef union fault_hdr {
    struct {
        unsigned long gen, seq;
        uintptr_t next, prev;    /* masked fault_hdr pointers */
    } h;
    max_align_t align;           /* keeps the user block aligned as malloc's */
} fault_hdr;

typedef struct fault_state {
    pthread_mutex_t lock;
    unsigned long gen;           /* current run */
    unsigned long seq;           /* allocations of this run */
    unsigned long fail_at;       /* 0: none */
    unsigned long trace_at;      /* FREP_FAULT_TRACE: print this allocation's stack */
    int hit;
    size_t live;                 /* blocks of this run alive */
    fault_hdr head;              /* list sentinel */
    void *frames[FAULT_FRAMES];  /* stack of the failed allocation */
    int nframes;
} fault_state;

/* The one state of the test program: the hook's user pointer points to it. */
static fault_state fault_st = { .lock = PTHREAD_MUTEX_INITIALIZER };

static fault_hdr *unmask(uintptr_t v) { return (fault_hdr *)(v ^ FAULT_LINK_MASK); }
static uintptr_t mask(fault_hdr *h) { return (uintptr_t)h ^ FAULT_LINK_MASK; }

static void link_block(fault_state *s, fault_hdr *b)
{
    fault_hdr *first = unmask(s->head.h.next);
    b->h.next = mask(first);
    b->h.prev = mask(&s->head);
    first->h.prev = mask(b);
    s->head.h.next = mask(b);
}

static void unlink_block(fault_hdr *b)
{
    unmask(b->h.prev)->h.next = b->h.next;
    unmask(b->h.next)->h.prev = b->h.prev;
}

static void print_stack(FILE *f, void *const *frames, int n)
{
#ifdef __GLIBC__
    char **names = backtrace_symbols(frames, n);
    for (int i = 0; i < n; i++) fprintf(f, "#     %s\n", names ? names[i] : "?");
    free(names);
#else
    for (int i = 0; i < n; i++) fprintf(f, "#     %p\n", frames[i]);
#endif
}

static int take_stack(void **frames)
{
#ifdef __GLIBC__
    return backtrace(frames, FAULT_FRAMES);
#else
    (void)frames;
    return 0;
#endif
}

/* Number the allocation; 0 when it is the one to fail. Called with the lock held. */
static int next_allocation(fault_state *s)
{
    unsigned long k = ++s->seq;
    if (k == s->trace_at) {
        void *fr[FAULT_FRAMES];
        int n = take_stack(fr);
        printf("# allocation %lu of run %lu:\n", k, s->gen);
        print_stack(stdout, fr, n);
    }
    if (k != s->fail_at) return 1;
    s->hit = 1;
    s->nframes = take_stack(s->frames);
    return 0;
}

static void *fault_alloc(void *user, void *p, size_t n)
{
    fault_state *s = user;
    fault_hdr *b = p ? (fault_hdr *)p - 1 : NULL;
    void *ret = NULL;
    pthread_mutex_lock(&s->lock);
    if (n == 0) {                                    /* free */
        unlink_block(b);
        if (b->h.gen == s->gen) s->live--;
        free(b);
    } else if (next_allocation(s)) {
        if (n > SIZE_MAX - sizeof *b) n = SIZE_MAX - sizeof *b;  /* realloc then fails */
        if (b) unlink_block(b);
        fault_hdr *nb = realloc(b, sizeof *b + n);
        if (!nb && b) link_block(s, b);             /* realloc failed: old block stays */
        if (nb) {
            if (!b) {
                nb->h.gen = s->gen;
                nb->h.seq = s->seq;
                s->live++;
            }
            link_block(s, nb);
            ret = nb + 1;
        }
    }
    pthread_mutex_unlock(&s->lock);
    return ret;
}

void fault_install(void)
{
    fault_state *s = &fault_st;
    s->head.h.next = s->head.h.prev = mask(&s->head);
    const char *t = getenv("FREP_FAULT_TRACE");
    s->trace_at = t ? strtoul(t, NULL, 10) : 0;
    frep_set_allocator(fault_alloc, s);
}

void fault_arm(unsigned long fail_at)
{
    fault_state *s = &fault_st;
    pthread_mutex_lock(&s->lock);
    s->gen++;
    s->seq = 0;
    s->fail_at = fail_at;
    s->hit = 0;
    s->live = 0;
    s->nframes = 0;
    pthread_mutex_unlock(&s->lock);
}

unsigned long fault_count(void)
{
    pthread_mutex_lock(&fault_st.lock);
    unsigned long k = fault_st.seq;
    pthread_mutex_unlock(&fault_st.lock);
    return k;
}

int fault_hit(void)
{
    pthread_mutex_lock(&fault_st.lock);
    int h = fault_st.hit;
    pthread_mutex_unlock(&fault_st.lock);
    return h;
}

size_t fault_live(void)
{
    pthread_mutex_lock(&fault_st.lock);
    size_t n = fault_st.live;
    pthread_mutex_unlock(&fault_st.lock);
    return n;
}

void fault_report(FILE *f, size_t max)
{
    fault_state *s = &fault_st;
    pthread_mutex_lock(&s->lock);
    if (s->hit) {
        fprintf(f, "#   failed allocation %lu, allocated from:\n", s->fail_at);
        print_stack(f, s->frames, s->nframes);
    }
    size_t shown = 0;
    for (fault_hdr *b = unmask(s->head.h.next); b != &s->head && shown < max;
         b = unmask(b->h.next))
        if (b->h.gen == s->gen) {
            fprintf(f, "#   leaked: block of allocation %lu (FREP_FAULT_TRACE=%lu shows it)\n",
                    b->h.seq, b->h.seq);
            shown++;
        }
    pthread_mutex_unlock(&s->lock);
}

int fault_failed_in(const char *fn)
{
    int found = 0;
    pthread_mutex_lock(&fault_st.lock);
#ifdef __GLIBC__
    for (int i = 0; i < fault_st.nframes && !found; i++) {
        Dl_info info;
        found = dladdr(fault_st.frames[i], &info) && info.dli_sname &&
                strcmp(info.dli_sname, fn) == 0;
    }
#else
    (void)fn;
#endif
    pthread_mutex_unlock(&fault_st.lock);
    return found;
}
