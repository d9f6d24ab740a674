/* Version of the library and program. */
#ifndef WAVEFUEL_VERSION_H
#define WAVEFUEL_VERSION_H

#define WF_VERSION "0.1.0"

/* `git describe --always --dirty` of the source tree the library was built from ("unknown" outside a checkout): a
 * static string. One object holds it (src/util/version.c), rebuilt whenever the description changes, so that an
 * incremental build never records the hash of an older tree in its results. */
const char *wf_git_hash(void);

#endif
