/* serve.c - the loopback HTTP server of serve.h: a listening socket on 127.0.0.1 and
 * up to VIEW_MAX_CLIENTS connections in one pollfd array; each connection sends one
 * GET, gets one reply, and is closed.
 */
#include "config.h"

#include "alloc.h"
#include "serve.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

typedef struct view_client {
    int fd;                  /* -1: free slot */
    size_t len;
    double since;            /* seconds (monotonic) when accepted */
    char req[VIEW_MAX_REQUEST + 1];
} view_client;

struct frep_view_server {
    int fd, port;
    view_client c[VIEW_MAX_CLIENTS];
};

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

view_server *view_server_open(int port, frep_error *e)
{
    view_server *s = frep_calloc(1, sizeof *s);
    if (!s) {
        frep_error_nomem(e);
        return NULL;
    }
    for (int i = 0; i < VIEW_MAX_CLIENTS; i++) s->c[i].fd = -1;
    s->fd = socket(AF_INET, SOCK_STREAM, 0);
    int one = 1;
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons((uint16_t)port);
    socklen_t alen = sizeof a;
    if (s->fd < 0 || setsockopt(s->fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) != 0 ||
        bind(s->fd, (struct sockaddr *)&a, sizeof a) != 0 || listen(s->fd, 16) != 0 ||
        fcntl(s->fd, F_SETFL, O_NONBLOCK) != 0 ||
        getsockname(s->fd, (struct sockaddr *)&a, &alen) != 0) {
        frep_error_set(e, FREP_EIO, "cannot listen on 127.0.0.1:%d: %s", port, strerror(errno));
        if (s->fd >= 0) close(s->fd);
        frep_free(s);
        return NULL;
    }
    s->port = ntohs(a.sin_port);
    return s;
}

int view_server_port(const view_server *s) { return s->port; }

static void drop(view_client *c)
{
    close(c->fd);
    c->fd = -1;
    c->len = 0;
}

/* All of n bytes, or give up (the client went away or stalled past the timeout). */
static int send_all(int fd, const char *p, size_t n)
{
    while (n > 0) {
        ssize_t k = send(fd, p, n, MSG_NOSIGNAL);
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) return -1;
        p += k;
        n -= (size_t)k;
    }
    return 0;
}

static void reply(view_client *c, int status, const char *type, const char *body, size_t len)
{
    char head[256];
    const char *what = status == 200 ? "OK" : status == 404 ? "Not Found"
                     : status == 431 ? "Request Header Fields Too Large" : "Bad Request";
    int n = snprintf(head, sizeof head, "HTTP/1.0 %d %s\r\nContent-Type: %s\r\n"
                     "Content-Length: %zu\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
                     status, what, type, len);
    int fl = fcntl(c->fd, F_GETFL);
    if (fl != -1) fcntl(c->fd, F_SETFL, fl & ~O_NONBLOCK);
    struct timeval tv = { VIEW_SEND_TIMEOUT_S, 0 };
    setsockopt(c->fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
    if (send_all(c->fd, head, (size_t)n) == 0) send_all(c->fd, body, len);
    drop(c);
}

/* A complete request head in c->req: answer a GET, refuse anything else. */
static void answer(view_client *c, view_route_fn route, void *user)
{
    char path[1024];
    if (sscanf(c->req, "GET %1023s HTTP/", path) != 1) {
        reply(c, 400, "text/plain", "bad request\n", 12);
        return;
    }
    view_reply r = { 404, "text/plain", "not found\n", 10 };
    route(user, path, &r);
    reply(c, r.status, r.type, r.body, r.len);
}

/* Read what client c sent; answer when the head is complete. */
static int client_read(view_client *c, view_route_fn route, void *user)
{
    ssize_t k = recv(c->fd, c->req + c->len, VIEW_MAX_REQUEST - c->len, 0);
    if (k < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return 0;
    if (k <= 0) {
        drop(c);
        return 0;
    }
    c->len += (size_t)k;
    c->req[c->len] = '\0';
    if (strstr(c->req, "\r\n\r\n") || strstr(c->req, "\n\n")) {
        answer(c, route, user);
        return 1;
    }
    if (c->len == VIEW_MAX_REQUEST) reply(c, 431, "text/plain", "request too large\n", 18);
    return 0;
}

/* New connections into free slots (the rest wait in the backlog). */
static void accept_clients(view_server *s)
{
    for (int i = 0; i < VIEW_MAX_CLIENTS; i++) {
        if (s->c[i].fd >= 0) continue;
        int fd = accept(s->fd, NULL, NULL);
        if (fd < 0) return;
        fcntl(fd, F_SETFL, O_NONBLOCK);
        s->c[i].fd = fd;
        s->c[i].len = 0;
        s->c[i].since = now_s();
    }
}

int view_server_step(view_server *s, int timeout_ms, view_route_fn route, void *user)
{
    struct pollfd p[VIEW_MAX_CLIENTS + 1];
    int map[VIEW_MAX_CLIENTS + 1], n = 0;
    p[n] = (struct pollfd){ s->fd, POLLIN, 0 };
    map[n++] = -1;
    for (int i = 0; i < VIEW_MAX_CLIENTS; i++)
        if (s->c[i].fd >= 0) {
            p[n] = (struct pollfd){ s->c[i].fd, POLLIN, 0 };
            map[n++] = i;
        }
    int r = poll(p, (nfds_t)n, timeout_ms);
    if (r < 0) return errno == EINTR ? -1 : 0;
    int answered = 0;
    for (int k = 1; k < n; k++)
        if (p[k].revents) answered += client_read(&s->c[map[k]], route, user);
    if (p[0].revents & POLLIN) accept_clients(s);
    double t = now_s();
    for (int i = 0; i < VIEW_MAX_CLIENTS; i++)
        if (s->c[i].fd >= 0 && (t - s->c[i].since) * 1000 > VIEW_CLIENT_TIMEOUT_MS) drop(&s->c[i]);
    return answered;
}

void view_server_close(view_server *s)
{
    if (!s) return;
    for (int i = 0; i < VIEW_MAX_CLIENTS; i++)
        if (s->c[i].fd >= 0) close(s->c[i].fd);
    close(s->fd);
    frep_free(s);
}
