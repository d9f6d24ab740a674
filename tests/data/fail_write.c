/* Test-only LD_PRELOAD library: makes writes to a result file (a path ending in ".h5.partial") fail on demand, as
 * a full disk, a quota or a failing device would, at a chosen point of a run (tests/t_disk_full.sh).
 *   WF_FAIL_WRITE_AT=N      the N-th pwrite/write on such a file (1 = the first) and the following ones fail
 *   WF_FAIL_WRITE_COUNT=M   only M calls fail from there (default 0: all of them)
 *   WF_FAIL_ERRNO=E         errno of the failures: EIO (default), ENOSPC, EDQUOT or EFBIG
 *   WF_FAIL_FALLOCATE_AT=K  the K-th posix_fallocate on such a file and the following ones fail with WF_FAIL_ERRNO
 *   WF_STOP_AT_FALLOCATE=K  the process stops itself (SIGSTOP) before the K-th posix_fallocate, so that a test can
 *                           fill the disk before it reserves space, then continue it (SIGCONT)
 *   WF_FAIL_LOG=PATH        at exit, append "writes=W fallocates=F first=W0" to PATH: the calls seen on such files,
 *                           and the writes made before the first posix_fallocate (the file's creation) 
 * Build: cc -shared -fPIC fail_write.c -o fail_write.so -ldl */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <unistd.h>

static long n_writes, n_falloc, writes_before_falloc = -1;

static long env_long(const char *name)
{
    const char *s = getenv(name);
    return s ? strtol(s, NULL, 10) : 0;
}

static int fail_errno(void)
{
    const char *s = getenv("WF_FAIL_ERRNO");
    if (!s || !strcmp(s, "EIO")) return EIO;
    if (!strcmp(s, "ENOSPC")) return ENOSPC;
    if (!strcmp(s, "EDQUOT")) return EDQUOT;
    if (!strcmp(s, "EFBIG")) return EFBIG;
    return EIO;
}

static int is_result(int fd)
{
    char link[64], path[4096];
    snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    ssize_t n = readlink(link, path, sizeof path - 1);
    if (n <= 0) return 0;
    path[n] = '\0';
    size_t len = (size_t)n, suf = strlen(".h5.partial");
    return len >= suf && !strcmp(path + len - suf, ".h5.partial");
}

/* Counts the call; 1 when it must fail. */
static int must_fail(long *counter, const char *at_var, const char *count_var)
{
    long k = __atomic_add_fetch(counter, 1, __ATOMIC_SEQ_CST);
    long at = env_long(at_var), count = count_var ? env_long(count_var) : 0;
    return at > 0 && k >= at && (count <= 0 || k < at + count);
}

ssize_t pwrite(int fd, const void *buf, size_t n, off_t off)
{
    static ssize_t (*real)(int, const void *, size_t, off_t);
    if (!real) real = (ssize_t (*)(int, const void *, size_t, off_t))dlsym(RTLD_NEXT, "pwrite");
    if (is_result(fd) && must_fail(&n_writes, "WF_FAIL_WRITE_AT", "WF_FAIL_WRITE_COUNT")) {
        errno = fail_errno();
        return -1;
    }
    return real(fd, buf, n, off);
}

ssize_t write(int fd, const void *buf, size_t n)
{
    static ssize_t (*real)(int, const void *, size_t);
    if (!real) real = (ssize_t (*)(int, const void *, size_t))dlsym(RTLD_NEXT, "write");
    if (fd > 2 && is_result(fd) && must_fail(&n_writes, "WF_FAIL_WRITE_AT", "WF_FAIL_WRITE_COUNT")) {
        errno = fail_errno();
        return -1;
    }
    return real(fd, buf, n);
}

int posix_fallocate(int fd, off_t off, off_t len)
{
    static int (*real)(int, off_t, off_t);
    if (!real) real = (int (*)(int, off_t, off_t))dlsym(RTLD_NEXT, "posix_fallocate");
    if (!is_result(fd)) return real(fd, off, len);
    if (writes_before_falloc < 0) writes_before_falloc = n_writes;
    if (must_fail(&n_falloc, "WF_FAIL_FALLOCATE_AT", NULL)) return fail_errno();
    if (env_long("WF_STOP_AT_FALLOCATE") == n_falloc) raise(SIGSTOP);
    return real(fd, off, len);
}

__attribute__((destructor)) static void report(void)
{
    const char *log = getenv("WF_FAIL_LOG");
    if (!log) return;
    FILE *f = fopen(log, "a");
    if (!f) return;
    fprintf(f, "writes=%ld fallocates=%ld first=%ld\n", n_writes, n_falloc, writes_before_falloc);
    fclose(f);
}
