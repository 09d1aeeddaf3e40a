/* serve.h - the loopback HTTP server of `frep view --watch`: 127.0.0.1 only, one
 * poll(2) loop without threads, a bounded number of clients each answered once
 * (HTTP/1.0, Connection: close).  The caller routes paths to replies; the server
 * never prints.
 */
#ifndef FREP_SERVE_H
#define FREP_SERVE_H

#include <stddef.h>

#include "err.h"
#include "frep.h"

/* Limits, each with its reason. */
#define VIEW_MAX_CLIENTS 16           /* a browser opens a handful of connections; more
                                         wait in the listen backlog */
#define VIEW_MAX_REQUEST 8192         /* the request line and headers of a GET: larger
                                         requests are not the viewer's and get 431 */
#define VIEW_CLIENT_TIMEOUT_MS 5000   /* a client that sends no full request in this
                                         time is dropped, so it cannot hold a slot */
#define VIEW_SEND_TIMEOUT_S 10        /* a reply not taken in this time is abandoned: the
                                         loop must go on re-meshing */

/* A reply and the route function are the public API's (runtime/frep.h): status 200 or
 * 404, a content type, the body (not copied; it must live until the route function is
 * called again).  The route fills *r for the path of a GET (query string included). */
typedef frep_view_reply view_reply;
typedef frep_view_route_fn view_route_fn;

typedef struct frep_view_server view_server;

/* Listen on 127.0.0.1:port (0: any free port).  NULL with *e set when the port is
 * taken or sockets fail (FREP_EIO), or out of memory. */
view_server *view_server_open(int port, frep_error *e);
/* The port listened on. */
int view_server_port(const view_server *s);
/* Wait up to timeout_ms for the network, accept, read, answer what is complete, drop
 * clients past VIEW_CLIENT_TIMEOUT_MS.  Returns the number of requests answered, or
 * -1 when poll was interrupted by a signal (the caller checks its flag). */
int view_server_step(view_server *s, int timeout_ms, view_route_fn route, void *user);
void view_server_close(view_server *s);

#endif
