/* correct_explain.c — sc_corr_explain: the sentence for each reason a table image is refused
 * (correct_reason.h). Its own file, so that a microcontroller build not calling it links no
 * sentence. Freestanding. */
#include "correct_reason.h"
#include "selfcal/correct.h"

static const char *const reason_text[SC_CORR_R_COUNT] = {
    [SC_CORR_R_OK] = "ok",
    [SC_CORR_R_PROFILE_AXIS] = "a profile's axis or dir is not x, y or z",
    [SC_CORR_R_PROFILE_ENC] = "a profile's value encoding is unknown",
    [SC_CORR_R_PROFILE_RESERVED] = "a profile header's reserved bytes are not zero",
    [SC_CORR_R_PROFILE_N] = "a profile has fewer than 2 points",
    [SC_CORR_R_PROFILE_EXTENT] = "a profile's start or last point is not finite or beyond +-1e6 mm",
    [SC_CORR_R_PROFILE_STEP] = "a profile's step is not finite or below 1e-6 mm",
    [SC_CORR_R_PROFILE_SCALE] = "a profile's value scale is 0 or can express more than +-2147.48 um (int16 codes: scale <= 65536 pm; int32: 1 pm)",
    [SC_CORR_R_SHORT] = "shorter than a table's header and checksum",
    [SC_CORR_R_MAGIC] = "not a selfcal table (bad magic bytes)",
    [SC_CORR_R_VERSION] = "unsupported table format version",
    [SC_CORR_R_FILE_BYTES] = "truncated or wrong length: the file's size differs from the size its header states",
    [SC_CORR_R_CRC] = "checksum mismatch: the table is corrupted",
    [SC_CORR_R_HEADER] = "the header's size field is not 64 or its reserved bytes are not zero",
    [SC_CORR_R_GRID_N] = "the grid has fewer than 2 nodes along x or y",
    [SC_CORR_R_PROFILES] = "more than 8 profiles",
    [SC_CORR_R_GRID_ENC] = "the grid's value encoding is unknown",
    [SC_CORR_R_ORIGIN] = "the grid's origin is not finite or beyond +-1e6 mm",
    [SC_CORR_R_PITCH] = "the grid's pitch is not finite or below 1e-6 mm",
    [SC_CORR_R_EXTENT] = "the grid's last node is beyond +-1e6 mm",
    [SC_CORR_R_GRID_SCALE] = "the grid's value scale is 0 or can express more than +-2147.48 um (int16 codes: scale <= 65536 pm; int32: 1 pm)",
    [SC_CORR_R_BLOCKS_PAST_END] = "truncated: the grid and profiles the header states run past the end of the file",
    [SC_CORR_R_BLOCKS_FILL] = "wrong length: the grid, profiles and provenance the header states do not fill the file exactly",
    [SC_CORR_R_METHOD] = "the provenance's method name is not NUL-terminated",
    [SC_CORR_R_SIGMA] = "the provenance's sigma is not finite",
    [SC_CORR_R_SOURCES] = "the provenance has more than 9 sources or reserved bytes not zero",
    [SC_CORR_R_PROV_SIZE] = "wrong length: the provenance's size disagrees with its number of sources",
    [SC_CORR_R_CAP_GRID] = "the grid has more nodes than this build's SC_CORR_MAX_NX x SC_CORR_MAX_NY",
    [SC_CORR_R_CAP_PROFILES] = "more profiles than this build's SC_CORR_MAX_PROFILES",
    [SC_CORR_R_CAP_POINTS] = "a profile has more points than this build's SC_CORR_MAX_PROFILE_POINTS",
};

const char *sc_corr_explain(const void *buf, size_t len)
{
    unsigned r = sc_corr_check_reason(buf, len);
    return r < SC_CORR_R_COUNT && reason_text[r] ? reason_text[r] : "unknown table error";
}
