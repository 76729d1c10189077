/* row_writer.c — the writers' rows, formatted by two threads where a file is large: a second
 * thread formats chunks of rows while this one formats others and writes every chunk in order
 * (io_internal.h: sc_io_out_rows). Formatting the numbers is most of a large write (docs/profile.md:
 * 10⁶ points); the second core is idle while a command writes its result. */
#define _GNU_SOURCE /* sync_file_range */
#include <fcntl.h>
#include <pthread.h>
#include <stdlib.h>

#include "io_internal.h"

#define CHUNK_ROWS 2048
#define SLOTS 4 /* chunks formatted ahead of the one being written */

typedef struct chunk_slot {
    char *buf; /* CHUNK_ROWS · SC_IO_ROW_MAX bytes: pages are touched only as far as rows reach */
    size_t len;
    int ready;
} chunk_slot;

typedef struct row_pipeline {
    pthread_mutex_t lock;
    pthread_cond_t changed;
    long n, chunks, next_format, next_write; /* chunk c holds rows c·CHUNK_ROWS .. */
    sc_io_format_row format;
    const void *ctx;
    chunk_slot slot[SLOTS];
} row_pipeline;

static size_t format_chunk(const row_pipeline *q, long c, char *buf)
{
    long a = c * CHUNK_ROWS, b = a + CHUNK_ROWS < q->n ? a + CHUNK_ROWS : q->n;
    char *p = buf;
    for (long i = a; i < b; ++i)
        p = q->format(q->ctx, i, p);
    return (size_t)(p - buf);
}

/* Claim the next chunk to format if its slot is free (lock held): its number, or -1. */
static long claim(row_pipeline *q)
{
    if (q->next_format < q->chunks && q->next_format < q->next_write + SLOTS)
        return q->next_format++;
    return -1;
}

/* Format chunk c outside the lock, then hand it to the writer (lock held on entry and exit). */
static void format_claimed(row_pipeline *q, long c)
{
    chunk_slot *s = &q->slot[c % SLOTS];
    pthread_mutex_unlock(&q->lock);
    size_t len = format_chunk(q, c, s->buf);
    pthread_mutex_lock(&q->lock);
    s->len = len;
    s->ready = 1;
    pthread_cond_broadcast(&q->changed);
}

static void *format_helper(void *arg)
{
    row_pipeline *q = arg;
    pthread_mutex_lock(&q->lock);
    while (q->next_format < q->chunks) {
        long c = claim(q);
        if (c < 0)
            pthread_cond_wait(&q->changed, &q->lock);
        else
            format_claimed(q, c);
    }
    pthread_mutex_unlock(&q->lock);
    return NULL;
}

/* Every WRITEBACK_EVERY bytes the kernel is asked to start writing the file out (it would wait
 * for the commit's fsync otherwise, which then waits for all of it): the disk works while rows
 * are formatted. A hint: nothing changes if it is refused. */
#define WRITEBACK_EVERY ((long long)8 << 20)

static void start_writeback(FILE *fp, long long *from)
{
#if defined(__linux__) && !defined(SYNC_FILE_RANGE_WRITE)
#error "sync_file_range is Linux's: its declaration needs _GNU_SOURCE before the first include"
#endif
#ifdef SYNC_FILE_RANGE_WRITE
    long long at = (long long)ftello(fp);
    if (at - *from < WRITEBACK_EVERY || fflush(fp) != 0)
        return;
    (void)sync_file_range(fileno(fp), (off_t)*from, (off_t)(at - *from), SYNC_FILE_RANGE_WRITE);
    *from = at;
#else
    (void)fp, (void)from;
#endif
}

/* This thread: write the next chunk when it is ready, else format one, else wait. */
static void write_chunks(row_pipeline *q, sc_io_out *o)
{
    FILE *fp = o->f.fp;
    long long written_back = (long long)ftello(fp);
    pthread_mutex_lock(&q->lock);
    while (q->next_write < q->chunks) {
        chunk_slot *s = &q->slot[q->next_write % SLOTS];
        long c;
        if (s->ready) {
            pthread_mutex_unlock(&q->lock);
            sc_io_out_write(o, s->buf, s->len); /* a failure's errno: sc_io_out_drain */
            start_writeback(fp, &written_back);
            pthread_mutex_lock(&q->lock);
            s->ready = 0;
            q->next_write++;
            pthread_cond_broadcast(&q->changed);
        } else if ((c = claim(q)) >= 0) {
            format_claimed(q, c);
        } else {
            pthread_cond_wait(&q->changed, &q->lock);
        }
    }
    pthread_mutex_unlock(&q->lock);
}

/* Two threads; 0 if they could not start (nothing written then; o->nomem for want of memory). */
static int write_rows_two_threads(sc_io_out *o, long n, sc_io_format_row format, const void *ctx)
{
    row_pipeline q = {.n = n, .chunks = (n + CHUNK_ROWS - 1) / CHUNK_ROWS, .format = format,
                      .ctx = ctx};
    int ok = 1;
    for (int k = 0; k < SLOTS; ++k)
        ok &= (q.slot[k].buf = malloc((size_t)CHUNK_ROWS * SC_IO_ROW_MAX)) != NULL;
    o->nomem = !ok;
    pthread_t helper;
    int locks = ok && pthread_mutex_init(&q.lock, NULL) == 0;
    int conds = locks && pthread_cond_init(&q.changed, NULL) == 0;
    int helping = conds && pthread_create(&helper, NULL, format_helper, &q) == 0;
    if (helping) {
        sc_io_out_flush(o);
        write_chunks(&q, o);
        pthread_join(helper, NULL);
    }
    if (conds)
        pthread_cond_destroy(&q.changed);
    if (locks)
        pthread_mutex_destroy(&q.lock);
    for (int k = 0; k < SLOTS; ++k)
        free(q.slot[k].buf);
    return helping;
}

void sc_io_out_rows_tuned(sc_io_out *o, long n, sc_io_format_row format, const void *ctx,
                          long parallel_from)
{
    if (n >= parallel_from && n > CHUNK_ROWS && sc_io_cpus_available() > 1 &&
        (write_rows_two_threads(o, n, format, ctx) || o->nomem))
        return;
    for (long i = 0; i < n; ++i) {
        o->p = format(ctx, i, o->p);
        sc_io_out_row(o);
    }
}

void sc_io_out_rows(sc_io_out *o, long n, sc_io_format_row format, const void *ctx)
{
    sc_io_out_rows_tuned(o, n, format, ctx, SC_IO_PARALLEL_ROWS);
}
