/* header.c — owns the declarative `# key = value` header parser (selfcal/header.h): one table of
 * keys per format instead of a hand-written chain of strcmp/parse/range/duplicate checks in every
 * reader. Small enough that no library would be simpler; it reuses csv.c's strict number parsing. */
#include <stdio.h>
#include <string.h>

#include "selfcal/csv.h"
#include "selfcal/header.h"

void sc_header_init(sc_header *h, const sc_header_key *keys, int n_keys, void *dst)
{
    memset(h, 0, sizeof *h);
    h->keys = keys;
    h->n_keys = n_keys > SC_HEADER_MAX_KEYS ? SC_HEADER_MAX_KEYS : n_keys;
    h->dst = dst;
}

static int find_key(const sc_header *h, const char *key)
{
    for (int k = 0; k < h->n_keys; ++k)
        if (!strcmp(h->keys[k].key, key))
            return k;
    return -1;
}

/* Range check of one number; SC_OK or SC_E_INPUT naming key, value text and the rule. */
static sc_status check_range(const sc_header_key *d, double v, const char *text, const char *path,
                             long line, sc_error *err)
{
    int excl = (d->flags & SC_HEADER_MIN_EXCLUSIVE) != 0;
    int low = excl ? !(v > d->min) : !(v >= d->min), high = !(v <= d->max);
    if (!low && !high)
        return SC_OK;
    if (d->type == SC_HEADER_LONG || d->type == SC_HEADER_LONG_PAIR)
        return sc_error_set(err, SC_E_INPUT, path, line, "%s = %s is out of range (%.0f..%.0f)",
                            d->key, text, d->min, d->max);
    if (low && d->min == 0)
        return sc_error_set(err, SC_E_INPUT, path, line, "%s = %s must be %s", d->key, text,
                            excl ? "positive" : "non-negative");
    if (low)
        return sc_error_set(err, SC_E_INPUT, path, line, "%s = %s must be %s %g", d->key, text,
                            excl ? ">" : ">=", d->min);
    return sc_error_set(err, SC_E_INPUT, path, line, "%s = %s is beyond any real set-up (> %g)",
                        d->key, text, d->max);
}

/* Parse one number of type long (is_long) or double from s into *v. */
static int parse_number(const char *s, int is_long, double *v)
{
    if (is_long) {
        long l;
        if (sc_parse_long(s, &l) != 0)
            return -1;
        *v = (double)l;
        return 0;
    }
    return sc_parse_double(s, v);
}

/* Parse the value text of key d into v[0] (and v[1] for pairs); SC_E_INPUT if malformed. */
static sc_status parse_value(const sc_header_key *d, const char *value, double v[2],
                             const char *path, long line, sc_error *err)
{
    int is_long = d->type == SC_HEADER_LONG || d->type == SC_HEADER_LONG_PAIR;
    int pair = d->type == SC_HEADER_DOUBLE_PAIR || d->type == SC_HEADER_LONG_PAIR;
    const char *what = is_long ? "a whole number" : "a number";
    if (!pair) {
        if (parse_number(value, is_long, &v[0]) != 0)
            return sc_error_set(err, SC_E_INPUT, path, line, "%s: '%.40s' is not %s", d->key,
                                value, what);
        return SC_OK;
    }
    char buf[128];
    snprintf(buf, sizeof buf, "%s", value);
    char *comma = strchr(buf, ',');
    if (comma)
        *comma = '\0';
    if (!comma || strlen(value) >= sizeof buf ||
        parse_number(sc_str_trim(buf), is_long, &v[0]) != 0 ||
        parse_number(sc_str_trim(comma + 1), is_long, &v[1]) != 0)
        return sc_error_set(err, SC_E_INPUT, path, line, "%s: '%.40s' is not two %ss 'a,b'",
                            d->key, value, is_long ? "whole number" : "number");
    return SC_OK;
}

static void store(const sc_header_key *d, void *dst, const double v[2])
{
    char *p = (char *)dst + d->offset;
    switch (d->type) {
    case SC_HEADER_LONG: *(long *)(void *)p = (long)v[0]; break;
    case SC_HEADER_DOUBLE: *(double *)(void *)p = v[0]; break;
    case SC_HEADER_DOUBLE_PAIR: memcpy(p, v, 2 * sizeof(double)); break;
    case SC_HEADER_LONG_PAIR: {
        long l[2] = {(long)v[0], (long)v[1]};
        memcpy(p, l, sizeof l);
        break;
    }
    }
}

sc_status sc_header_line(sc_header *h, const char *path, long line, const char *text, bool *used,
                         sc_error *err)
{
    if (used)
        *used = false;
    char buf[1024], key[64], *value;
    if (strlen(text) >= sizeof buf)
        return SC_OK; /* longer than any header line of ours: not a key line */
    snprintf(buf, sizeof buf, "%s", text);
    if (!sc_header_kv(buf, key, sizeof key, &value))
        return SC_OK;
    int k = find_key(h, key);
    if (k < 0)
        return SC_OK;
    const sc_header_key *d = &h->keys[k];
    if (h->line[k])
        return sc_error_set(err, SC_E_INPUT, path, line, "%s given twice (first at line %ld)",
                            key, h->line[k]);
    double v[2] = {0, 0};
    sc_status st = parse_value(d, value, v, path, line, err);
    int pair = d->type == SC_HEADER_DOUBLE_PAIR || d->type == SC_HEADER_LONG_PAIR;
    for (int m = 0; st == SC_OK && m < 1 + pair; ++m)
        st = check_range(d, v[m], value, path, line, err);
    if (st != SC_OK)
        return st;
    store(d, h->dst, v);
    h->line[k] = line;
    if (used)
        *used = true;
    return SC_OK;
}

sc_status sc_header_finish(const sc_header *h, const char *path, long line, sc_error *err)
{
    for (int k = 0; k < h->n_keys; ++k)
        if (h->keys[k].required && !h->line[k])
            return sc_error_set(err, SC_E_INPUT, path, line, "header line '# %s = ...' missing",
                                h->keys[k].key);
    return SC_OK;
}

long sc_header_line_of(const sc_header *h, const char *key)
{
    int k = find_key(h, key);
    return k < 0 ? 0 : h->line[k];
}
