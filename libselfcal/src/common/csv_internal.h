/* csv_internal.h — private: the line reader (selfcal/csv.h) over part of a regular file, for the
 * readers that split a large file between two threads (io/profile_file.c). */
#ifndef SELFCAL_CSV_INTERNAL_H
#define SELFCAL_CSV_INTERNAL_H

#include "selfcal/csv.h"

/* 1 if the text of a line is one the readers skip: blank (isspace only) or a comment ('#' after
 * leading blanks). What SC_CSV_MAX_SKIP_RUN counts. */
int sc_csv_text_skippable(const char *s);

/* The byte offset in the file of the current line's first byte. */
long long sc_csv_line_offset(const sc_csv *r);

/* Open a second reader w on the regular file r reads (a file description of its own, so both can
 * read at once), from byte offset at (a line start); w counts its lines from 1 there. SC_E_IO
 * when r is not reading a regular file or the file cannot be opened again. */
sc_status sc_csv_open_at(sc_csv *w, const sc_csv *r, long long at, sc_error *err);

#endif
