/* api.c - the pieces every job of the public API shares (api/api.h) and the version
 * query: errors and warnings to the caller's callback, atomic file output.
 */
#include "config.h"

#include "api.h"

#include <errno.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "alloc.h"
#include "util.h"

const char *frep_version(void)
{
    return PACKAGE_VERSION;
}

void api_report(const api_diag *d, frep_severity sev, const char *message)
{
    if (!d || !d->fn) return;
    frep_diag fd;
    memset(&fd, 0, sizeof fd);
    fd.severity = sev;
    fd.message = message;
    d->fn(d->user, &fd);
}

int api_fail(const api_diag *d, const frep_error *e)
{
    api_report(d, FREP_ERROR, e && e->code != FREP_EOK && e->msg[0] ? e->msg : "out of memory");
    return -1;
}

/* frep_report_runtime_error's diagnostic, turned into a warning: the job goes on
 * (those points are NaN). */
static void as_warning(void *user, const frep_diag *d)
{
    const api_diag *ad = user;
    frep_diag w = *d;
    w.severity = FREP_WARNING;
    ad->fn(ad->user, &w);
}

void api_runtime_warning(const api_diag *d, const frep_program *p, const frep_runtime_error *re)
{
    if (!d || !d->fn || !re->count) return;
    api_diag to = *d;
    frep_report_runtime_error(p, re, as_warning, &to);
}

int api_write_atomic(const api_diag *d, const char *path, int (*fn)(FILE *f, void *ctx),
                     void *ctx)
{
    frep_error e;
    frep_error_init(&e);
    if (!path) {
        frep_error_set(&e, FREP_EINPUT, "no output path");
        return api_fail(d, &e);
    }
    if (strcmp(path, "-") == 0) {
        if (fn(stdout, ctx) == 0 && fflush(stdout) == 0) return 0;
        frep_error_set(&e, FREP_EIO, "cannot write to standard output: %s", strerror(errno));
        return api_fail(d, &e);
    }
    /* An existing output that is no regular file (a device such as /dev/null, a FIFO)
     * is written in place: a temporary renamed over it would replace the device or the
     * pipe with a plain file. */
    struct stat st;
    int in_place = stat(path, &st) == 0 && !S_ISREG(st.st_mode);
    char *tmp = in_place ? frep_strdupf("%s", path)
                         : frep_strdupf("%s.tmp%ld", path, (long)getpid());
    if (!tmp) return api_fail(d, &e);
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        frep_error_set(&e, FREP_EIO, "cannot write %s: %s", path, strerror(errno));
        frep_free(tmp);
        return api_fail(d, &e);
    }
    int rc = fn(f, ctx);
    int saved = errno;
    if (fflush(f) != 0 || ferror(f)) rc = -1, saved = errno;
    if (fclose(f) != 0) rc = -1, saved = errno;
    if (rc == 0 && !in_place && rename(tmp, path) != 0) rc = -1, saved = errno;
    if (rc != 0) {
        if (!in_place) remove(tmp);
        frep_error_set(&e, FREP_EIO, "cannot write %s: %s", path,
                       saved ? strerror(saved) : "write error");
    }
    frep_free(tmp);
    return rc == 0 ? 0 : api_fail(d, &e);
}

void api_model_box(const frep_program *p, const frep_mesh_options *o, double box[6])
{
    if (o->has_box) {
        memcpy(box, o->box, 6 * sizeof *box);
        return;
    }
    if (frep_program_box(p, box)) return;
    for (int i = 0; i < 3; i++) {
        box[i] = -API_DEFAULT_BOX;
        box[i + 3] = API_DEFAULT_BOX;
    }
}
