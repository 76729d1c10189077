/* runtime/transport_fake.c — in-process test transport over a socketpair (static state). */
#include "transport_fake.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

typedef struct fake_state {
    int fd[2]; /* [0] daemon side, [1] test side */
    uint32_t bad;
} fake_state;

static fake_state g_fake = {{-1, -1}, 0};

int sc_fake_peer_fd(void)
{
    return g_fake.fd[1];
}

uint32_t sc_fake_bad_requests(void)
{
    return g_fake.bad;
}

static sc_status fake_open(void *state, sc_error *err)
{
    fake_state *s = state;
    if (socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, s->fd) != 0) {
        return sc_error_set(err, SC_E_IO, NULL, 0, "fake: socketpair: %s", strerror(errno));
    }
    /* The daemon's end never blocks; the test's end is an ordinary blocking socket. */
    fcntl(s->fd[0], F_SETFL, fcntl(s->fd[0], F_GETFL) | O_NONBLOCK);
    s->bad = 0;
    return SC_OK;
}

static int fake_fill(void *state, struct pollfd *fds, int max)
{
    fake_state *s = state;
    if (max < 1 || s->fd[0] < 0)
        return 0;
    fds[0].fd = s->fd[0];
    fds[0].events = POLLIN;
    fds[0].revents = 0;
    return 1;
}

static void fake_serve(void *state, struct pollfd *fds, int n, sc_engine *e, uint64_t now_ms)
{
    (void)now_ms;
    fake_state *s = state;
    if (n < 1 || !(fds[0].revents & POLLIN))
        return;
    for (;;) {
        unsigned char req[16];
        ssize_t r = recv(s->fd[0], req, sizeof req, 0);
        if (r < 0)
            return;
        if (r != 8) {
            s->bad++;
            continue;
        }
        int32_t in[2];
        memcpy(in, req, sizeof in);
        sc_fake_answer a;
        memset(&a, 0, sizeof a);
        a.status = sc_engine_correct(e, in[0], in[1], &a.x_nm, &a.y_nm);
        a.count = (uint16_t)(e->corrections & 0xffffu);
        unsigned char out[12];
        memcpy(out, &a.x_nm, 4);
        memcpy(out + 4, &a.y_nm, 4);
        memcpy(out + 8, &a.status, 2);
        memcpy(out + 10, &a.count, 2);
        if (send(s->fd[0], out, sizeof out, MSG_NOSIGNAL) < 0)
            s->bad++;
    }
}

static void fake_close(void *state)
{
    fake_state *s = state;
    for (int i = 0; i < 2; i++) {
        if (s->fd[i] >= 0)
            close(s->fd[i]);
        s->fd[i] = -1;
    }
}

void sc_fake_transport(sc_transport *t)
{
    t->name = "fake";
    t->state = &g_fake;
    t->open = fake_open;
    t->fill_pollfds = fake_fill;
    t->serve = fake_serve;
    t->tick = NULL;
    t->close = fake_close;
}
