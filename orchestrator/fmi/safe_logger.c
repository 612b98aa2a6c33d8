/*
 * The FMI 2.0 logger callback of rotorcosim's master, formatting an FMU's message without
 * trusting it (orchestrator/fmi/safe_log.py builds and loads this file).
 *
 * FMI 2.0 (section 2.1.5, fmi2CallbackLogger) makes the message a printf format whose
 * arguments follow it. A master must format it in C: Python (ctypes) cannot read the variable
 * arguments. Handing the message to vsnprintf, as fmpy's logger proxy does, trusts the FMU
 * twice: that every conversion has its argument, and that every %s argument points at a
 * string. An FMU that breaks either takes the master's process down: a PythonFMU slave that
 * raises an exception whose text holds "%s" or "%n" has its text passed on as the format with
 * no arguments (cppfmu's Logger::Log), and vsnprintf then reads a pointer from a register and
 * dereferences it, or writes through one (%n).
 *
 * Here the format is interpreted one conversion at a time:
 *   - every string the FMU hands over (instance name, category, message, each %s argument) is
 *     copied through a pipe first: write(2) from an address that is not readable fails with
 *     EFAULT instead of faulting, so an unreadable string becomes "(unreadable)", and a %s
 *     argument holding control characters (other than tab, line ends and escape) "(not text)";
 *   - %n writes nothing (its argument is consumed);
 *   - at most MAX_ARGS arguments are read (va_arg past the arguments the FMU gave reads
 *     registers and the caller's stack, which are readable, but no further than that), field
 *     widths and the precisions of numbers are capped at MAX_FIELD (the precision of %s only
 *     shortens the string: not capped), and a format using positional arguments ("%1$s") is
 *     shown from there on as it is;
 *   - the message, after formatting, is cut at OUT_CAP bytes.
 * Every other conversion is formatted by snprintf with its single argument, so a well-formed
 * message reads exactly as vsnprintf would print it.
 */
#if defined(__linux__) && !defined(_GNU_SOURCE)
#define _GNU_SOURCE      /* pipe2 */
#endif
#include <errno.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <fcntl.h>
#include <sys/ioctl.h>
#include <unistd.h>

#define OUT_CAP 4096     /* bytes of a formatted message */
#define FMT_CAP 4096     /* bytes of a format read */
#define STR_CAP OUT_CAP  /* bytes of a %s argument read: as many as the message may hold */
#define NAME_CAP 256     /* bytes of the instance name and the category read */
#define MAX_ARGS 64      /* arguments read from the variable argument list */
#define MAX_FIELD 512    /* largest field width and precision */

typedef void (*target_logger)(void *env, const char *instance, int status, const char *category,
                              const char *message);

static target_logger target = NULL;

/* Copy the NUL-terminated string at p (at most cap - 1 bytes) into dst through the pipe fds.
   Returns its length, or -1 when p is NULL or its first byte cannot be read. Reads go page by
   page, so a string that runs into an unreadable page is cut there; then *cut (when not NULL)
   is set to 1 (it is left alone otherwise: a string found whole, or one cut at cap - 1 bytes). */
static long copy_string(const int fds[2], const char *p, char *dst, size_t cap, int *cut) {
    size_t n = 0;
    if (p == NULL || cap == 0 || fds[0] < 0) return -1;
    while (n + 1 < cap) {
        uintptr_t at = (uintptr_t)(p + n);
        size_t chunk = 4096 - (size_t)(at % 4096);
        if (chunk > cap - 1 - n) chunk = cap - 1 - n;
        ssize_t put;
        do put = write(fds[1], (const void *)at, chunk); while (put < 0 && errno == EINTR);
        if (put <= 0) break;
        ssize_t got = 0;
        while (got < put) {
            ssize_t r = read(fds[0], dst + n + (size_t)got, (size_t)(put - got));
            if (r < 0 && errno == EINTR) continue;
            if (r <= 0) break;
            got += r;
        }
        if (got < put) break;
        void *end = memchr(dst + n, 0, (size_t)got);
        if (end != NULL) return (long)((char *)end - dst);
        n += (size_t)got;
        if ((size_t)put < chunk) break;
    }
    if (n == 0) return -1;
    if (n + 1 < cap && cut != NULL) *cut = 1;      /* stopped before its NUL and before cap */
    dst[n] = 0;
    return (long)n;
}

/* Text has no control characters but tab, newline, carriage return and escape (colour codes;
   shown escaped like the rest of the message, orchestrator/fmi/subsystem.py). A %s whose argument
   the FMU did not pass reads a pointer from a register or the stack; where that happens to
   point at readable memory, what is there is almost never text, and is not shown. */
static int is_text(const char *p) {
    for (const unsigned char *c = (const unsigned char *)p; *c; c++)
        if ((*c < 0x20 && *c != '\t' && *c != '\n' && *c != '\r' && *c != 0x1b) || *c == 0x7f) return 0;
    return 1;
}

/* append text to out (length *len, capacity OUT_CAP) */
static void put(char *out, size_t *len, const char *text, size_t n) {
    if (*len + 1 >= OUT_CAP) return;
    if (n > OUT_CAP - 1 - *len) n = OUT_CAP - 1 - *len;
    memcpy(out + *len, text, n);
    *len += n;
    out[*len] = 0;
}

static void put_formatted(char *out, size_t *len, int wrote) {
    /* snprintf wrote into out + *len with the room left; it returns the length it wanted */
    if (wrote < 0) return;
    size_t room = OUT_CAP - 1 - *len;
    *len += (size_t)wrote < room ? (size_t)wrote : room;
    out[*len] = 0;
}

static int field(int v) { return v < 0 ? (v < -MAX_FIELD ? -MAX_FIELD : v) : (v > MAX_FIELD ? MAX_FIELD : v); }

/* format fmt with the arguments in ap into out (OUT_CAP bytes) */
static void format_message(const int fds[2], const char *fmt, va_list ap, char *out) {
    size_t len = 0;
    int args = 0;
    char spec[64], arg[STR_CAP];
    out[0] = 0;
    for (const char *c = fmt; *c;) {
        if (*c != '%') {
            const char *next = strchr(c, '%');
            size_t n = next ? (size_t)(next - c) : strlen(c);
            put(out, &len, c, n);
            c += n;
            continue;
        }
        const char *start = c++;
        if (*c == '%') { put(out, &len, "%", 1); c++; continue; }
        /* %[flags][width][.precision][length]conversion */
        size_t s = 0;
        spec[s++] = '%';
        while (*c && strchr("-+ #0'", *c) && s < 16) spec[s++] = *c++;
        int width = -1, precision = -1, star_w = 0, star_p = 0, positional = 0;
        if (*c == '*') { star_w = 1; c++; }
        else if (*c >= '0' && *c <= '9') { width = 0; while (*c >= '0' && *c <= '9') { width = width < 100000 ? width * 10 + (*c - '0') : width; c++; } }
        if (*c == '$') positional = 1;
        if (*c == '.') {
            c++;
            if (*c == '*') { star_p = 1; c++; }
            else { precision = 0; while (*c >= '0' && *c <= '9') { precision = precision < 100000 ? precision * 10 + (*c - '0') : precision; c++; } }
        }
        char lm[3] = {0, 0, 0};
        if (*c == 'h' || *c == 'l') { lm[0] = *c++; if (*c == lm[0]) lm[1] = *c++; }
        else if (*c && strchr("Ljztq", *c)) lm[0] = *c++;
        char conv = *c;
        int known = conv && strchr("diouxXcseEfFgGaApnm", conv) != NULL;
        if (positional || !known || args + star_w + star_p + (conv != 'm') > MAX_ARGS) {
            /* not interpreted: the rest of the format as it is */
            put(out, &len, start, strlen(start));
            break;
        }
        c++;
        if (star_w) { width = va_arg(ap, int); args++; }
        if (star_p) { precision = va_arg(ap, int); args++; }
        /* spec: '%', the flags, the width and the precision as numbers (capped), then the
           length modifier and the conversion; %c, %s and %p take no length modifier here */
        if (width != -1 || star_w) s += (size_t)snprintf(spec + s, sizeof spec - s, "%d", field(width));
        if (precision >= 0)
            s += (size_t)snprintf(spec + s, sizeof spec - s, ".%d", conv == 's' ? precision : field(precision));
        if (conv != 'c' && conv != 's' && conv != 'p')
            for (int k = 0; k < 2 && lm[k]; k++) spec[s++] = lm[k];
        spec[s++] = conv;
        spec[s] = 0;
        char *at = out + len;
        size_t room = OUT_CAP - len;
        if (room <= 1) break;
        args += conv != 'm';
        switch (conv) {
        case 'd': case 'i':
            if ((lm[0] == 'l' && lm[1] == 'l') || lm[0] == 'L') put_formatted(out, &len, snprintf(at, room, spec, va_arg(ap, long long)));
            else if (lm[0] == 'l') put_formatted(out, &len, snprintf(at, room, spec, va_arg(ap, long)));
            else if (lm[0] == 'j') put_formatted(out, &len, snprintf(at, room, spec, va_arg(ap, intmax_t)));
            else if (lm[0] == 'z' || lm[0] == 't') put_formatted(out, &len, snprintf(at, room, spec, va_arg(ap, ptrdiff_t)));
            else if (lm[0] == 'q') put_formatted(out, &len, snprintf(at, room, spec, va_arg(ap, long long)));
            else put_formatted(out, &len, snprintf(at, room, spec, va_arg(ap, int)));
            break;
        case 'o': case 'u': case 'x': case 'X':
            if ((lm[0] == 'l' && lm[1] == 'l') || lm[0] == 'L') put_formatted(out, &len, snprintf(at, room, spec, va_arg(ap, unsigned long long)));
            else if (lm[0] == 'l') put_formatted(out, &len, snprintf(at, room, spec, va_arg(ap, unsigned long)));
            else if (lm[0] == 'j') put_formatted(out, &len, snprintf(at, room, spec, va_arg(ap, uintmax_t)));
            else if (lm[0] == 'z' || lm[0] == 't') put_formatted(out, &len, snprintf(at, room, spec, va_arg(ap, size_t)));
            else if (lm[0] == 'q') put_formatted(out, &len, snprintf(at, room, spec, va_arg(ap, unsigned long long)));
            else put_formatted(out, &len, snprintf(at, room, spec, va_arg(ap, unsigned int)));
            break;
        case 'c':               /* %lc (a wide character): its low byte, never converted */
            put_formatted(out, &len, snprintf(at, room, spec, (int)(unsigned char)va_arg(ap, int)));
            break;
        case 'e': case 'E': case 'f': case 'F': case 'g': case 'G': case 'a': case 'A':
            if (lm[0] == 'L') put_formatted(out, &len, snprintf(at, room, spec, va_arg(ap, long double)));
            else put_formatted(out, &len, snprintf(at, room, spec, va_arg(ap, double)));
            break;
        case 'p':
            put_formatted(out, &len, snprintf(at, room, spec, va_arg(ap, void *)));
            break;
        case 'n':
            (void)va_arg(ap, void *);       /* nothing is written through the FMU's pointer */
            break;
        case 'm':
            put(out, &len, "%m", 2);        /* glibc's strerror(errno): errno is not the FMU's here */
            break;
        case 's': {
            const char *p = va_arg(ap, const char *);
            if (lm[0] == 'l') { put(out, &len, "(wide string)", 13); break; }
            size_t cap = STR_CAP;
            if (precision >= 0 && (size_t)precision + 1 < cap) cap = (size_t)precision + 1;
            long n = copy_string(fds, p, arg, cap, NULL);
            if (n < 0) strcpy(arg, p == NULL ? "(null)" : "(unreadable)");
            else if (!is_text(arg)) strcpy(arg, "(not text)");
            put_formatted(out, &len, snprintf(at, room, spec, arg));
            break;
        }
        }
    }
}

/* The pipe every string of an FMU is read through: one per thread, kept open (a pipe made and
   closed per value cost 8 us of the 9 a String value took), made again in a child after fork
   and whenever a read left bytes in it. */
static __thread int tl_fds[2] = {-1, -1};
static __thread pid_t tl_pid = 0;

/* This thread's pipe; {-1, -1} when none can be made (copy_string then reads nothing). */
static const int *thread_pipe(void) {
    if (tl_fds[0] >= 0 && tl_pid != getpid()) {      /* inherited through fork: this process's copies */
        close(tl_fds[0]); close(tl_fds[1]);
        tl_fds[0] = tl_fds[1] = -1;
    }
    if (tl_fds[0] < 0) {
#if defined(__linux__)
        if (pipe2(tl_fds, O_CLOEXEC) != 0) tl_fds[0] = tl_fds[1] = -1;
#else
        if (pipe(tl_fds) != 0) tl_fds[0] = tl_fds[1] = -1;
#endif
        tl_pid = getpid();
    }
    return tl_fds;
}

/* After a use of thread_pipe(): a pipe that still holds bytes is closed (never read stale bytes). */
static void done_with_pipe(void) {
    int left = 0;
    if (tl_fds[0] >= 0 && (ioctl(tl_fds[0], FIONREAD, &left) != 0 || left != 0)) {
        close(tl_fds[0]); close(tl_fds[1]);
        tl_fds[0] = tl_fds[1] = -1;
    }
}

static void safe_logger(void *env, const char *instance, int status, const char *category,
                        const char *message, ...) {
    if (target == NULL) return;
    const int *fds = thread_pipe();
    char name[NAME_CAP], cat[NAME_CAP], fmt[FMT_CAP], out[OUT_CAP];
    if (copy_string(fds, instance, name, sizeof name, NULL) < 0) strcpy(name, "?");
    if (copy_string(fds, category, cat, sizeof cat, NULL) < 0) strcpy(cat, "");
    if (copy_string(fds, message, fmt, sizeof fmt, NULL) < 0) {
        strcpy(out, message == NULL ? "" : "(unreadable message)");
    } else {
        va_list ap;
        va_start(ap, message);
        format_message(fds, fmt, ap, out);
        va_end(ap);
    }
    done_with_pipe();
    target(env, name, status, cat, out);
}

/* The logger callback to hand to FMUs; calls `logger` with the formatted message. */
void *rotorcosim_safe_logger(target_logger logger) {
    target = logger;
    return (void *)&safe_logger;
}

/* Format `message` with the arguments given (tests: the formatting alone, without an FMU). */
int rotorcosim_format(char *out, const char *message, ...) {
    const int *fds = thread_pipe();
    char fmt[FMT_CAP];
    if (fds[0] < 0) return -1;
    long n = copy_string(fds, message, fmt, sizeof fmt, NULL);
    if (n >= 0) {
        va_list ap;
        va_start(ap, message);
        format_message(fds, fmt, ap, out);
        va_end(ap);
    } else {
        strcpy(out, "(unreadable message)");
    }
    done_with_pipe();
    return (int)strlen(out);
}

/* Copy the NUL-terminated string an FMU handed over at p (fmi2GetString) into out (at most
   cap - 1 bytes, NUL-terminated), reading it through a pipe as the logger does. Returns its
   length, -1 when p cannot be read at all, or -2 when no pipe could be made. A string longer
   than cap - 1 bytes, or one running into unreadable memory, is cut there (the length returned
   is then cap - 1 or what could be read); *cut is 1 in the second case, else 0. */
long rotorcosim_copy_string(const char *p, char *out, size_t cap, int *cut) {
    if (cut != NULL) *cut = 0;
    if (cap == 0) return -1;
    const int *fds = thread_pipe();
    if (fds[0] < 0) return -2;
    long n = copy_string(fds, p, out, cap, cut);
    done_with_pipe();
    return n;
}
