/* Path helpers (path.h): joining relative to a file, directory parts, the running executable's directory. */
#include "util/path.h"

#include <stdio.h>
#include <string.h>
#include <unistd.h>

int wf_path_relative_to(const char *base_file, const char *rel, char *out, size_t len)
{
    const char *slash = strrchr(base_file, '/');
    int w = rel[0] == '/' || !slash ? snprintf(out, len, "%s", rel)
                                    : snprintf(out, len, "%.*s/%s", (int)(slash - base_file), base_file, rel);
    return w < 0 || (size_t)w >= len ? -1 : 0;
}

const char *wf_path_plain_name_problem(const char *name, size_t max_len)
{
    if (!name[0]) return "is empty";
    if (strchr(name, '/')) return "contains '/' (a name, not a path: it names output/NAME.h5)";
    if (!strcmp(name, ".") || !strcmp(name, "..")) return "is '.' or '..'";
    for (const char *p = name; *p; p++)
        if ((unsigned char)*p < 0x20 || *p == 0x7f) return "contains a control character";
    if (strlen(name) > max_len) return "is too long";
    return NULL;
}

const char *wf_path_base(const char *path)
{
    const char *slash = strrchr(path, '/');
    return slash ? slash + 1 : path;
}

int wf_path_dirname(const char *path, int levels, char *out, size_t len)
{
    int w = snprintf(out, len, "%s", path);
    if (w < 0 || (size_t)w >= len) return -1;
    for (int i = 0; i < levels; i++) {
        char *slash = strrchr(out, '/');
        if (!slash) return -1;
        /* "/x" has the root as its directory: keep the '/'. */
        if (slash == out) slash[1] = '\0';
        else *slash = '\0';
    }
    return 0;
}

int wf_path_exe_dir(char *out, size_t len)
{
    char exe[4096];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n <= 0) return -1;
    exe[n] = '\0';
    return wf_path_dirname(exe, 1, out, len);
}
