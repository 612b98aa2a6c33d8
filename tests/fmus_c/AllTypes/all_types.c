/* AllTypes: a native FMI 2.0 co-simulation test FMU with ports of every variable type.
 *
 * Real:        gain (parameter, [0, 100]), u (input), y = gain*u (output; 0 when mode = Off),
 *              x (output, initial="exact": a state, x' = u), f[0..2] (inputs), g[i] = gain*f[i] (outputs)
 * Integer:     n_in (input), count (output, initial="exact"; count += 1 + n_in per doStep),
 *              stop_after (parameter, >= 0: when count >= stop_after > 0 the FMU ends the simulation:
 *              fmi2DoStep returns fmi2Discard and fmi2GetBooleanStatus(fmi2Terminated) is true),
 *              n_out = 2*n_in (output)
 * Boolean:     b_in (input), b_out = b_in XOR (count is odd) (output)
 * Enumeration: mode (parameter, Mode: Off=1, Slow=2, Fast=3), e_in (input), e_out = e_in (output)
 * String:      label (parameter), s_in (input), s_out = s_in, or label when s_in is empty (output);
 *              a String whose value is "<NULL>" is returned by fmi2GetString as a NULL pointer,
 *              one whose value is "<BADPTR>" as the address 16, which cannot be read, and one
 *              whose value is "<EDGE>" as the text "ends at an unreadable page" without its NUL,
 *              placed at the very end of a readable page followed by one that cannot be read
 *              (an FMU that breaks FMI 2.0: the master's tests of what it records then)
 *
 * The FMU enforces the FMI 2.0 co-simulation state machine (sec. 4.2.4) and answers every
 * illegal call with fmi2Error and a log message "<function>: illegal call sequence ...", as the
 * Modelica Reference FMUs do. Built with -DFIXED_STEP it also refuses a communication step size
 * that differs from the first one (its model description then says
 * canHandleVariableCommunicationStepSize="false").
 */
#define _DEFAULT_SOURCE      /* MAP_ANONYMOUS under -std=c99 */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <sys/mman.h>
#include <unistd.h>

#include "fmi2Functions.h"

#define MODEL_GUID "{3b1f6a52-0c1e-4d6e-9a51-a11c0de7e5a1}"

enum { R_GAIN, R_U, R_Y, R_X, R_F0, R_F1, R_F2, R_G0, R_G1, R_G2,
       I_N_IN, I_COUNT, I_STOP_AFTER, I_N_OUT, B_IN, B_OUT, E_MODE, E_IN, E_OUT, S_LABEL, S_IN, S_OUT, N_VARS };

typedef enum { ST_INSTANTIATED = 1, ST_INITIALIZATION = 2, ST_STEP_COMPLETE = 4, ST_STEP_FAILED = 8,
               ST_TERMINATED = 16, ST_ERROR = 32 } ModelState;

#define STR_LEN 256
typedef struct {
    double r[N_VARS];
    int i[N_VARS];          /* Integer, Enumeration and Boolean values by value reference */
    char s[N_VARS][STR_LEN];
    double time, first_h;
    int terminated;
    ModelState state;
} Data;

typedef struct {
    Data d;
    char *instanceName;
    fmi2CallbackFunctions cb;
    fmi2Boolean loggingOn;
} Instance;

/* which variables may be set in which state: inputs always (but not after a failed step),
 * parameters and initial="exact" variables before fmi2ExitInitializationMode only */
static int is_input(fmi2ValueReference r)
{
    return r == R_U || r == R_F0 || r == R_F1 || r == R_F2 || r == I_N_IN || r == B_IN || r == E_IN || r == S_IN;
}
static int is_init_settable(fmi2ValueReference r)
{
    return r == R_GAIN || r == R_X || r == I_COUNT || r == I_STOP_AFTER || r == E_MODE || r == S_LABEL;
}
static int type_of(fmi2ValueReference r)   /* 0 Real, 1 Integer/Enumeration, 2 Boolean, 3 String */
{
    if (r <= R_G2) return 0;
    if (r == B_IN || r == B_OUT) return 2;
    if (r >= S_LABEL) return 3;
    return 1;
}

static void logf_(Instance *inst, fmi2Status status, const char *fmt, ...)
{
    char msg[512], esc[1024];
    va_list ap;
    size_t k, j = 0;
    if (!inst || !inst->cb.logger) return;
    if (status == fmi2OK && !inst->loggingOn) return;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    for (k = 0; msg[k] && j + 2 < sizeof esc; k++) {
        esc[j++] = msg[k];
        if (msg[k] == '%') esc[j++] = '%';
    }
    esc[j] = '\0';
    inst->cb.logger(inst->cb.componentEnvironment, inst->instanceName, status,
                    status == fmi2OK ? "logEvents" : "logStatusError", esc);
}

static int bad(fmi2Component c, const char *fn, int allowed)
{
    Instance *inst = (Instance *)c;
    if (!inst) return 1;
    if (!(inst->d.state & allowed)) {
        logf_(inst, fmi2Error, "%s: illegal call sequence (state %d)", fn, (int)inst->d.state);
        return 1;
    }
    return 0;
}

static void outputs(Data *d)
{
    int k;
    double g = d->i[E_MODE] == 1 ? 0.0 : d->r[R_GAIN];
    d->r[R_Y] = g * d->r[R_U];
    for (k = 0; k < 3; k++) d->r[R_G0 + k] = d->r[R_GAIN] * d->r[R_F0 + k];
    d->i[I_N_OUT] = 2 * d->i[I_N_IN];
    d->i[B_OUT] = (d->i[B_IN] != 0) != ((d->i[I_COUNT] & 1) != 0);
    d->i[E_OUT] = d->i[E_IN];
    strcpy(d->s[S_OUT], d->s[S_IN][0] ? d->s[S_IN] : d->s[S_LABEL]);
}

static void reset(Data *d)
{
    memset(d, 0, sizeof *d);
    d->r[R_GAIN] = 2.0;
    d->i[E_MODE] = 2;
    d->i[E_IN] = 1;
    strcpy(d->s[S_LABEL], "alltypes");
    d->state = ST_INSTANTIATED;
    outputs(d);
}

#define ALL (ST_INSTANTIATED | ST_INITIALIZATION | ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED | ST_ERROR)
#define READABLE (ST_INITIALIZATION | ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED | ST_ERROR)
#define WRITABLE (ST_INSTANTIATED | ST_INITIALIZATION | ST_STEP_COMPLETE)

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[])
{
    (void)n; (void)cat;
    if (bad(c, "fmi2SetDebugLogging", ALL)) return fmi2Error;
    ((Instance *)c)->loggingOn = on;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions *f, fmi2Boolean visible, fmi2Boolean loggingOn)
{
    Instance *inst;
    (void)res; (void)visible;
    if (!f || !f->allocateMemory || !f->freeMemory || !name || type != fmi2CoSimulation) return NULL;
    if (!guid || strcmp(guid, MODEL_GUID) != 0) {
        if (f->logger) f->logger(f->componentEnvironment, name, fmi2Error, "logStatusError", "wrong GUID");
        return NULL;
    }
    inst = (Instance *)f->allocateMemory(1, sizeof(Instance));
    if (!inst) return NULL;
    inst->instanceName = (char *)f->allocateMemory(strlen(name) + 1, 1);
    if (!inst->instanceName) { f->freeMemory(inst); return NULL; }
    strcpy(inst->instanceName, name);
    inst->cb = *f;
    inst->loggingOn = loggingOn;
    reset(&inst->d);
    return inst;
}

void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    if (!inst) return;
    inst->cb.freeMemory(inst->instanceName);
    inst->cb.freeMemory(inst);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real t0,
                               fmi2Boolean stopDef, fmi2Real tStop)
{
    (void)tolDef; (void)tol; (void)stopDef; (void)tStop;
    if (bad(c, "fmi2SetupExperiment", ST_INSTANTIATED)) return fmi2Error;
    ((Instance *)c)->d.time = t0;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    if (bad(c, "fmi2EnterInitializationMode", ST_INSTANTIATED)) return fmi2Error;
    ((Instance *)c)->d.state = ST_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    if (bad(c, "fmi2ExitInitializationMode", ST_INITIALIZATION)) return fmi2Error;
    ((Instance *)c)->d.state = ST_STEP_COMPLETE;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    if (bad(c, "fmi2Terminate", ST_STEP_COMPLETE | ST_STEP_FAILED)) return fmi2Error;
    ((Instance *)c)->d.state = ST_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    if (bad(c, "fmi2Reset", ALL)) return fmi2Error;
    reset(&((Instance *)c)->d);
    return fmi2OK;
}

/* common checks of a set call; returns 0 if the value reference r of type t may be set now */
static int check_set(Instance *inst, const char *fn, fmi2ValueReference r, int t)
{
    if (r >= N_VARS || type_of(r) != t) {
        logf_(inst, fmi2Error, "%s: unknown value reference %u", fn, r);
        return 1;
    }
    if (is_input(r)) return 0;
    if (is_init_settable(r) && inst->d.state != ST_STEP_COMPLETE) return 0;
    logf_(inst, fmi2Error, "%s: illegal call sequence: variable %u cannot be set in state %d", fn, r,
          (int)inst->d.state);
    return 1;
}

static int check_get(Instance *inst, const char *fn, fmi2ValueReference r, int t)
{
    if (r >= N_VARS || type_of(r) != t) {
        logf_(inst, fmi2Error, "%s: unknown value reference %u", fn, r);
        return 1;
    }
    return 0;
}

#define GETTER(NAME, T, TYPE, FIELD)                                                                  \
    fmi2Status NAME(fmi2Component c, const fmi2ValueReference vr[], size_t n, T value[])              \
    {                                                                                                 \
        Instance *inst = (Instance *)c;                                                               \
        size_t k;                                                                                     \
        if (bad(c, #NAME, READABLE)) return fmi2Error;                                                \
        outputs(&inst->d);                                                                            \
        for (k = 0; k < n; k++) {                                                                     \
            if (check_get(inst, #NAME, vr[k], TYPE)) return fmi2Error;                                \
            value[k] = FIELD;                                                                         \
        }                                                                                             \
        return fmi2OK;                                                                                \
    }

GETTER(fmi2GetReal, fmi2Real, 0, inst->d.r[vr[k]])
GETTER(fmi2GetInteger, fmi2Integer, 1, inst->d.i[vr[k]])
GETTER(fmi2GetBoolean, fmi2Boolean, 2, inst->d.i[vr[k]])
/* "<EDGE>": EDGE_TEXT without its NUL, ending at the last byte of a readable page whose next page
   cannot be read (mapped once per process, PROT_NONE behind it); NULL if the mapping failed */
#define EDGE_TEXT "ends at an unreadable page"
static fmi2String edge_string(void)
{
    static char *at = NULL;
    if (at == NULL) {
        long page = sysconf(_SC_PAGESIZE);
        char *p = mmap(NULL, 2 * (size_t)page, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (p == MAP_FAILED || mprotect(p + page, (size_t)page, PROT_NONE) != 0) return NULL;
        at = p + page - (sizeof EDGE_TEXT - 1);
        memcpy(at, EDGE_TEXT, sizeof EDGE_TEXT - 1);
    }
    return at;
}

GETTER(fmi2GetString, fmi2String, 3, strcmp(inst->d.s[vr[k]], "<NULL>") == 0 ? NULL :
       strcmp(inst->d.s[vr[k]], "<BADPTR>") == 0 ? (fmi2String)(uintptr_t)16 :
       strcmp(inst->d.s[vr[k]], "<EDGE>") == 0 ? edge_string() : inst->d.s[vr[k]])

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[])
{
    Instance *inst = (Instance *)c;
    size_t k;
    if (bad(c, "fmi2SetReal", WRITABLE)) return fmi2Error;
    for (k = 0; k < n; k++) {
        if (check_set(inst, "fmi2SetReal", vr[k], 0)) return fmi2Error;
        if (vr[k] == R_GAIN && (value[k] < 0.0 || value[k] > 100.0)) {
            logf_(inst, fmi2Error, "fmi2SetReal: gain = %g outside [0, 100]", value[k]);
            return fmi2Error;
        }
        inst->d.r[vr[k]] = value[k];
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer value[])
{
    Instance *inst = (Instance *)c;
    size_t k;
    if (bad(c, "fmi2SetInteger", WRITABLE)) return fmi2Error;
    for (k = 0; k < n; k++) {
        if (check_set(inst, "fmi2SetInteger", vr[k], 1)) return fmi2Error;
        if ((vr[k] == E_MODE || vr[k] == E_IN) && (value[k] < 1 || value[k] > 3)) {
            logf_(inst, fmi2Error, "fmi2SetInteger: enumeration value %d is not an item of Mode", value[k]);
            return fmi2Error;
        }
        inst->d.i[vr[k]] = value[k];
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean value[])
{
    Instance *inst = (Instance *)c;
    size_t k;
    if (bad(c, "fmi2SetBoolean", WRITABLE)) return fmi2Error;
    for (k = 0; k < n; k++) {
        if (check_set(inst, "fmi2SetBoolean", vr[k], 2)) return fmi2Error;
        inst->d.i[vr[k]] = value[k] ? 1 : 0;
    }
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String value[])
{
    Instance *inst = (Instance *)c;
    size_t k;
    if (bad(c, "fmi2SetString", WRITABLE)) return fmi2Error;
    for (k = 0; k < n; k++) {
        if (check_set(inst, "fmi2SetString", vr[k], 3)) return fmi2Error;
        if (!value[k] || strlen(value[k]) >= STR_LEN) {
            logf_(inst, fmi2Error, "fmi2SetString: NULL or longer than %d bytes", STR_LEN - 1);
            return fmi2Error;
        }
        strcpy(inst->d.s[vr[k]], value[k]);
    }
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior)
{
    Instance *inst = (Instance *)c;
    Data *d;
    (void)noSetPrior;
    if (bad(c, "fmi2DoStep", ST_STEP_COMPLETE)) return fmi2Error;
    d = &inst->d;
    if (fabs(t - d->time) > 1e-9 * (fabs(t) + 1.0)) {
        logf_(inst, fmi2Error, "fmi2DoStep: currentCommunicationPoint %.17g is not the FMU time %.17g", t, d->time);
        d->state = ST_ERROR;
        return fmi2Error;
    }
#ifdef FIXED_STEP
    if (d->first_h == 0.0) d->first_h = h;
    if (fabs(h - d->first_h) > 1e-12 * d->first_h) {
        logf_(inst, fmi2Error, "fmi2DoStep: communicationStepSize %.17g differs from the first one %.17g "
              "(canHandleVariableCommunicationStepSize is false)", h, d->first_h);
        d->state = ST_ERROR;
        return fmi2Error;
    }
#endif
    if (d->i[I_STOP_AFTER] > 0 && d->i[I_COUNT] >= d->i[I_STOP_AFTER]) {
        d->terminated = 1;
        d->state = ST_STEP_FAILED;
        logf_(inst, fmi2Discard, "fmi2DoStep: count reached stop_after = %d at t = %g; the simulation ends",
              d->i[I_STOP_AFTER], d->time);
        return fmi2Discard;
    }
    d->r[R_X] += d->r[R_U] * h;
    d->i[I_COUNT] += 1 + d->i[I_N_IN];
    d->time = t + h;
    outputs(d);
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v)
{
    (void)s; (void)v;
    if (bad(c, "fmi2GetStatus", READABLE)) return fmi2Error;
    return fmi2Discard;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v)
{
    if (bad(c, "fmi2GetRealStatus", READABLE)) return fmi2Error;
    if (s != fmi2LastSuccessfulTime) return fmi2Discard;
    *v = ((Instance *)c)->d.time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v)
{
    (void)s; (void)v;
    if (bad(c, "fmi2GetIntegerStatus", READABLE)) return fmi2Error;
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v)
{
    if (bad(c, "fmi2GetBooleanStatus", READABLE)) return fmi2Error;
    if (s != fmi2Terminated) return fmi2Discard;
    *v = ((Instance *)c)->d.terminated ? fmi2True : fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v)
{
    (void)s; (void)v;
    if (bad(c, "fmi2GetStringStatus", READABLE)) return fmi2Error;
    return fmi2Discard;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *st)
{
    Instance *inst = (Instance *)c;
    if (bad(c, "fmi2GetFMUstate", ALL)) return fmi2Error;
    if (!*st) {
        *st = inst->cb.allocateMemory(1, sizeof(Data));
        if (!*st) return fmi2Error;
    }
    memcpy(*st, &inst->d, sizeof(Data));
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate st)
{
    if (bad(c, "fmi2SetFMUstate", ALL) || !st) return fmi2Error;
    memcpy(&((Instance *)c)->d, st, sizeof(Data));
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *st)
{
    if (bad(c, "fmi2FreeFMUstate", ALL)) return fmi2Error;
    if (st && *st) { ((Instance *)c)->cb.freeMemory(*st); *st = NULL; }
    return fmi2OK;
}

#define UNSUPPORTED(PROTO, NAME) fmi2Status PROTO { logf_((Instance *)c, fmi2Error, NAME ": not supported"); return fmi2Error; }
UNSUPPORTED(fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n), "fmi2SerializedFMUstateSize")
UNSUPPORTED(fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n), "fmi2SerializeFMUstate")
UNSUPPORTED(fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s), "fmi2DeSerializeFMUstate")
UNSUPPORTED(fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu, const fmi2ValueReference z[], size_t nz, const fmi2Real dz[], fmi2Real du[]), "fmi2GetDirectionalDerivative")
UNSUPPORTED(fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], const fmi2Real v[]), "fmi2SetRealInputDerivatives")
UNSUPPORTED(fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], fmi2Real v[]), "fmi2GetRealOutputDerivatives")
