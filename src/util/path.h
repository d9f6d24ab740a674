/* The one path helper of wavefuel: paths written in a file (a scenario's grade profile, a class's table, a
 * sweep's scenario) are relative to that file's directory; directories derived from a file's path. Internal to
 * wavefuel. */
#ifndef WAVEFUEL_PATH_H
#define WAVEFUEL_PATH_H

#include <stddef.h>

/* out = `rel` if it is absolute or `base_file` has no directory part, else DIR(base_file)/rel. Returns 0, or -1
 * when the result does not fit in len bytes (out then holds a truncated string). */
int wf_path_relative_to(const char *base_file, const char *rel, char *out, size_t len);

/* Whether `name` can be used as a file name in a directory, as a scenario's or sweep's name is (output/NAME.h5):
 * NULL when it can, else why not ("contains '/'", "is empty", "is '..'", "contains a control character", "is
 * longer than MAX bytes" with max_len). A static string. */
const char *wf_path_plain_name_problem(const char *name, size_t max_len);

/* The file name part of `path`: what follows its last '/' (all of it when it has none); a pointer into path. */
const char *wf_path_base(const char *path);

/* out = the directory part of `path` up, `levels` times (1: the directory holding the file; 2: its parent).
 * Returns 0, or -1 when `path` has fewer than `levels` '/' or out (len bytes) is too small. */
int wf_path_dirname(const char *path, int levels, char *out, size_t len);

/* out = the directory of the running program's executable, from /proc/self/exe (Linux). Returns 0, or -1 when
 * it cannot be read or does not fit. */
int wf_path_exe_dir(char *out, size_t len);

#endif
