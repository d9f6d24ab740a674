/* The source tree's description (include/wavefuel/version.h): the Makefile passes WF_GIT_HASH to this file alone
 * and rebuilds it when `git describe` changes. */
#include "wavefuel/version.h"

#ifndef WF_GIT_HASH
#define WF_GIT_HASH "unknown"
#endif

const char *wf_git_hash(void) { return WF_GIT_HASH; }
