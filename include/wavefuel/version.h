/* Version of the library and program; WF_GIT_HASH is set by the Makefile from `git describe`. */
#ifndef WAVEFUEL_VERSION_H
#define WAVEFUEL_VERSION_H

#define WF_VERSION "0.1.0"
#ifndef WF_GIT_HASH
#define WF_GIT_HASH "unknown"
#endif

#endif
