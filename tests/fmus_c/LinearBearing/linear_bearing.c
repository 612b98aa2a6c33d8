/* LinearBearing: a native (C) FMI 2.0 co-simulation FMU.
 *
 * A linear isotropic spring-damper "journal bearing":
 *     Fx = -k x - c vx,   Fy = -k y - c vy      [N]
 * with the same variable names as rotorcosim's JournalBearing FMU (inputs x, y,
 * vx, vy, omega; outputs Fx, Fy), so it can replace it in a rotor scenario.
 * omega is accepted and ignored. The outputs are algebraic (direct feedthrough):
 * fmi2GetReal computes them from the current inputs; fmi2DoStep only advances
 * the time. Parameters k, c are fixed (settable before initialization ends).
 *
 * Value references (must match modelDescription.xml):
 *   0 k [N/m]  1 c [N s/m]  2 x  3 y  4 vx  5 vy  6 omega  7 Fx  8 Fy
 *
 * Built by tests/fmus_c/build_c_fmu.py (gcc -shared -fPIC -O2) against the
 * FMI 2.0 headers shipped with fmpy.
 *
 * Compiled with -DMISBEHAVING this source is the test FMU "MisbehavingBearing"
 * (tests/fmus_c/MisbehavingBearing/modelDescription.xml): the same bearing plus
 * two Integer parameters, fault (vr 9) and fault_step (vr 10, default 5). At the
 * fault_step-th call of fmi2DoStep of an instance (counted per instance, not
 * rolled back by fmi2SetFMUstate) it misbehaves on purpose:
 *   fault 0 nothing, 1 abort(), 2 a segmentation fault (write through NULL),
 *   3 _exit(3), 4 hang (sleeps forever, ignores nothing but SIGKILL in effect),
 *   5 NaN in Fx from then on (returns fmi2OK), 6 returns fmi2Error;
 *   7 a segmentation fault in fmi2FreeInstance (after a complete run; fault_step unused),
 *   8 a segmentation fault in fmi2ExitInitializationMode (before the first step; fault_step
 *     unused),
 *   9 log flooding: every fmi2DoStep from then on logs 2000 warnings of 1000 characters (returns fmi2OK),
 *   10 logs one warning with '%' conversions (escaped: they reach the importer as text), bytes that are
 *      not UTF-8 and terminal escape sequences, 100 000 characters long (returns fmi2OK),
 *   11 returns fmi2Pending (an asynchronous step the FMU never declared),
 *   12 returns the status code 42 (no fmi2Status),
 *   13 fmi2GetFMUstate returns fmi2OK without giving a state (NULL; fault_step unused),
 *   14 every fmi2DoStep from then on logs 500 warnings under another instance name, one that
 *      holds a terminal escape sequence ("other\x1b[2J"), as a confused or hostile FMU might,
 *   15 a hang in fmi2ExitInitializationMode (fault_step unused),
 *   16 logs three warnings with printf arguments: "%s" of a 3000-character string ending in
 *      "END", "%*.*f", "%-*d" and "%.*s" with negative widths and precisions, and conversions
 *      without their arguments ("%s %d %f %n"; tests/test_hostile_probe5.py),
 *   17 starts a thread of its own that logs 200 warnings with arguments while the importer
 *      goes on stepping; fmi2FreeInstance joins it (fault_step: the step that starts it),
 *   18 fmi2FreeInstance frees the instance, then logs one warning (fault_step unused).
 * It tests what a co-simulation master does when an FMU crashes or hangs.
 */

#ifdef MISBEHAVING
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdlib.h>
#include <pthread.h>
#include <time.h>
#include <unistd.h>
#endif
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"

#ifdef MISBEHAVING
#define MODEL_GUID "{5b0d7a52-0c1e-4d55-9f0e-6c7a43b1d002}"
enum { VR_K, VR_C, VR_X, VR_Y, VR_VX, VR_VY, VR_OMEGA, VR_FX, VR_FY, N_VARS, VR_FAULT = N_VARS, VR_FAULT_STEP };
#else
#define MODEL_GUID "{8c4e810f-3df3-4a00-8276-176fa3c9f001}"
enum { VR_K, VR_C, VR_X, VR_Y, VR_VX, VR_VY, VR_OMEGA, VR_FX, VR_FY, N_VARS };
#endif

typedef enum {
    ST_INSTANTIATED = 1,
    ST_INITIALIZATION = 2,
    ST_STEP_COMPLETE = 4,
    ST_TERMINATED = 8,
    ST_ERROR = 16
} ModelState;

typedef struct {
    double v[N_VARS];   /* all variables; outputs computed on demand */
    double time;
    ModelState state;
} Data;

typedef struct {
    Data d;
    char *instanceName;
    fmi2CallbackFunctions cb;   /* copy: the importer's struct may go away */
    fmi2Boolean loggingOn;
#ifdef MISBEHAVING
    int fault, fault_step, steps, nan;   /* steps: fmi2DoStep calls so far (not part of the FMU state) */
    int thread_started;                   /* fault 17: its logging thread runs (joined when freed) */
    pthread_t thread;
#endif
} Instance;

static const double START[N_VARS] = {1.0e6, 200.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};

/* ------------------------------------------------------------------ helpers */

static void logf_(Instance *inst, fmi2Status status, const char *category, const char *fmt, ...)
{
    char msg[512], esc[1024];
    va_list ap;
    size_t i, j = 0;
    if (!inst || !inst->cb.logger) return;
    if (status == fmi2OK && !inst->loggingOn) return;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    /* the message is a printf format for the importer: escape '%' */
    for (i = 0; msg[i] && j + 2 < sizeof esc; i++) {
        esc[j++] = msg[i];
        if (msg[i] == '%') esc[j++] = '%';
    }
    esc[j] = '\0';
    inst->cb.logger(inst->cb.componentEnvironment, inst->instanceName, status, category, esc);
}

static fmi2Status fail(Instance *inst, const char *fn, const char *why)
{
    logf_(inst, fmi2Error, "logStatusError", "%s: %s", fn, why);
    return fmi2Error;
}

/* check the instance and the allowed states; on a wrong state log and fail */
static int bad(fmi2Component c, const char *fn, int allowed)
{
    Instance *inst = (Instance *)c;
    if (!inst) return 1;
    if (!(inst->d.state & allowed)) {
        logf_(inst, fmi2Error, "logStatusError", "%s: not allowed in the current state (%d)", fn,
              (int)inst->d.state);
        return 1;
    }
    return 0;
}

static void compute_outputs(Data *d)
{
    d->v[VR_FX] = -d->v[VR_K] * d->v[VR_X] - d->v[VR_C] * d->v[VR_VX];
    d->v[VR_FY] = -d->v[VR_K] * d->v[VR_Y] - d->v[VR_C] * d->v[VR_VY];
}

#ifdef MISBEHAVING
/* fault 17: a thread of the FMU's own that logs while the importer steps it */
static void *log_thread(void *arg)
{
    Instance *inst = (Instance *)arg;
    int i;
    for (i = 0; i < 200; i++)
        inst->cb.logger(inst->cb.componentEnvironment, inst->instanceName, fmi2Warning, "logEvents",
                        "fault 17: message %d of %s from a thread of the FMU", i, "200");
    return NULL;
}

/* the fault of fmi2DoStep number inst->steps; returns fmi2Error for fault 6, else fmi2OK */
static fmi2Status misbehave(Instance *inst)
{
    struct timespec second = {1, 0};
    volatile int *nowhere = NULL;
    if (inst->fault == 9 && inst->steps >= inst->fault_step) {
        static char line[1001];
        int i;
        memset(line, 'w', sizeof line - 1);
        line[sizeof line - 1] = '\0';
        memcpy(line, "fault 9: ", 9);
        for (i = 0; i < 2000; i++)
            inst->cb.logger(inst->cb.componentEnvironment, inst->instanceName, fmi2Warning, "logEvents", line);
        return fmi2OK;
    }
    if (inst->fault == 14 && inst->steps >= inst->fault_step) {
        int i;
        for (i = 0; i < 500; i++)
            inst->cb.logger(inst->cb.componentEnvironment, "other\x1b[2J", fmi2Warning, "logEvents",
                            "fault 14: a message under another instance name");
        return fmi2OK;
    }
    if (inst->steps != inst->fault_step) return fmi2OK;
    switch (inst->fault) {
    case 1: abort();
    case 2: *nowhere = 1; return fmi2OK;            /* SIGSEGV */
    case 3: _exit(3);
    case 4: for (;;) nanosleep(&second, NULL);      /* hang */
    case 5: inst->nan = 1; return fmi2OK;
    case 6: return fail(inst, "fmi2DoStep", "fault 6: fmi2Error on purpose (MisbehavingBearing test FMU)");
    case 10: {
        static char big[100001];
        size_t i;
        const char *head = "fault 10: %%s %%n %%x \xff\xfe \x1b[2J\x1b]0;title\x07 ";
        for (i = 0; i < sizeof big - 1; i++) big[i] = (char)('a' + i % 26);
        big[sizeof big - 1] = '\0';
        memcpy(big, head, strlen(head));
        inst->cb.logger(inst->cb.componentEnvironment, inst->instanceName, fmi2Warning, "logEvents", big);
        return fmi2OK;
    }
    case 16: {
        static char arg[3001];
        memset(arg, 'a', sizeof arg - 1);
        arg[sizeof arg - 1] = '\0';
        memcpy(arg + sizeof arg - 5, "END", 4);
        inst->cb.logger(inst->cb.componentEnvironment, inst->instanceName, fmi2Warning, "logEvents",
                        "fault 16 long: %s", arg);
        inst->cb.logger(inst->cb.componentEnvironment, inst->instanceName, fmi2Warning, "logEvents",
                        "fault 16 star: [%*.*f] [%-*d] [%.*s]", -12, -3, 3.25, 6, 42, -1, "whole");
        inst->cb.logger(inst->cb.componentEnvironment, inst->instanceName, fmi2Warning, "logEvents",
                        "fault 16 missing: %s %d %f %n end");
        return fmi2OK;
    }
    case 17:
        if (!inst->thread_started && pthread_create(&inst->thread, NULL, log_thread, inst) == 0)
            inst->thread_started = 1;
        return fmi2OK;
    case 11: return (fmi2Status)5;                  /* fmi2Pending */
    case 12: return (fmi2Status)42;
    default: return fmi2OK;
    }
}
#endif

#define ALL_STATES (ST_INSTANTIATED | ST_INITIALIZATION | ST_STEP_COMPLETE | ST_TERMINATED | ST_ERROR)
#define RUNNING (ST_INITIALIZATION | ST_STEP_COMPLETE)

/* -------------------------------------------------------- inquiry, logging */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    (void)nCategories; (void)categories;
    if (bad(c, "fmi2SetDebugLogging", ALL_STATES)) return fmi2Error;
    ((Instance *)c)->loggingOn = loggingOn;
    return fmi2OK;
}

/* ------------------------------------------------------ create and destroy */

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    Instance *inst;
    (void)fmuResourceLocation; (void)visible;
    if (!functions || !functions->allocateMemory || !functions->freeMemory) return NULL;
    if (!instanceName || !instanceName[0]) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, "?", fmi2Error, "logStatusError",
                              "fmi2Instantiate: missing instance name");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                              "fmi2Instantiate: LinearBearing supports co-simulation only");
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, MODEL_GUID) != 0) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                              "fmi2Instantiate: wrong GUID (modelDescription.xml does not match the binary)");
        return NULL;
    }
    inst = (Instance *)functions->allocateMemory(1, sizeof(Instance));
    if (!inst) return NULL;
    inst->instanceName = (char *)functions->allocateMemory(strlen(instanceName) + 1, 1);
    if (!inst->instanceName) {
        functions->freeMemory(inst);
        return NULL;
    }
    strcpy(inst->instanceName, instanceName);
    inst->cb = *functions;
    inst->loggingOn = loggingOn;
    memcpy(inst->d.v, START, sizeof START);
    compute_outputs(&inst->d);
    inst->d.time = 0.0;
    inst->d.state = ST_INSTANTIATED;
#ifdef MISBEHAVING
    inst->fault = 0;
    inst->fault_step = 5;
    inst->steps = 0;
    inst->nan = 0;
    inst->thread_started = 0;
#endif
    logf_(inst, fmi2OK, "logEvents", "fmi2Instantiate: k = %g N/m, c = %g N s/m", inst->d.v[VR_K],
          inst->d.v[VR_C]);
    return inst;
}

void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    fmi2CallbackFreeMemory freeMemory;
    if (!inst) return;
#ifdef MISBEHAVING
    if (inst->fault == 7) {
        volatile int *nowhere = NULL;
        *nowhere = 1;                                /* SIGSEGV while freeing */
    }
    if (inst->thread_started) pthread_join(inst->thread, NULL);
#endif
    freeMemory = inst->cb.freeMemory;
#ifdef MISBEHAVING
    if (inst->fault == 18) {                         /* logs after its name was freed */
        char *name = inst->instanceName;
        fmi2CallbackLogger logger = inst->cb.logger;
        void *env = inst->cb.componentEnvironment;
        freeMemory(name);
        freeMemory(inst);
        logger(env, "bearing1", fmi2Warning, "logEvents", "fault 18: logged in fmi2FreeInstance after freeing %s",
               "its memory");
        return;
    }
#endif
    freeMemory(inst->instanceName);
    freeMemory(inst);
}

/* ------------------------------------------------------------ initialization */

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    Instance *inst = (Instance *)c;
    (void)toleranceDefined; (void)tolerance;
    if (bad(c, "fmi2SetupExperiment", ST_INSTANTIATED)) return fmi2Error;
    if (stopTimeDefined && stopTime < startTime)
        return fail(inst, "fmi2SetupExperiment", "stopTime < startTime");
    inst->d.time = startTime;
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
#ifdef MISBEHAVING
    if (((Instance *)c)->fault == 8) {
        volatile int *nowhere = NULL;
        *nowhere = 1;                                /* SIGSEGV while initializing */
    }
    if (((Instance *)c)->fault == 15) {
        struct timespec second = {1, 0};
        for (;;) nanosleep(&second, NULL);           /* hang while initializing */
    }
#endif
    ((Instance *)c)->d.state = ST_STEP_COMPLETE;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    if (bad(c, "fmi2Terminate", ST_STEP_COMPLETE)) return fmi2Error;
    ((Instance *)c)->d.state = ST_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    if (bad(c, "fmi2Reset", ALL_STATES)) return fmi2Error;
    memcpy(inst->d.v, START, sizeof START);
    compute_outputs(&inst->d);
    inst->d.time = 0.0;
    inst->d.state = ST_INSTANTIATED;
    return fmi2OK;
}

/* ---------------------------------------------------------- get/set values */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    Instance *inst = (Instance *)c;
    size_t i;
    if (bad(c, "fmi2GetReal", ST_INITIALIZATION | ST_STEP_COMPLETE | ST_TERMINATED | ST_ERROR))
        return fmi2Error;
    if (nvr > 0 && (!vr || !value)) return fail(inst, "fmi2GetReal", "NULL argument");
    compute_outputs(&inst->d);
#ifdef MISBEHAVING
    if (inst->nan) inst->d.v[VR_FX] = NAN;
#endif
    for (i = 0; i < nvr; i++) {
        if (vr[i] >= N_VARS) {
            logf_(inst, fmi2Error, "logStatusError", "fmi2GetReal: unknown value reference %u", vr[i]);
            return fmi2Error;
        }
        value[i] = inst->d.v[vr[i]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    Instance *inst = (Instance *)c;
    size_t i;
    if (bad(c, "fmi2SetReal", ST_INSTANTIATED | ST_INITIALIZATION | ST_STEP_COMPLETE)) return fmi2Error;
    if (nvr > 0 && (!vr || !value)) return fail(inst, "fmi2SetReal", "NULL argument");
    for (i = 0; i < nvr; i++) {
        fmi2ValueReference r = vr[i];
        if (r >= N_VARS) {
            logf_(inst, fmi2Error, "logStatusError", "fmi2SetReal: unknown value reference %u", r);
            return fmi2Error;
        }
        if (r == VR_FX || r == VR_FY) {
            logf_(inst, fmi2Error, "logStatusError", "fmi2SetReal: %s is an output and cannot be set",
                  r == VR_FX ? "Fx" : "Fy");
            return fmi2Error;
        }
        if ((r == VR_K || r == VR_C) && inst->d.state == ST_STEP_COMPLETE) {
            logf_(inst, fmi2Error, "logStatusError",
                  "fmi2SetReal: parameter %s is fixed; set it before fmi2ExitInitializationMode",
                  r == VR_K ? "k" : "c");
            return fmi2Error;
        }
        inst->d.v[r] = value[i];
    }
    return fmi2OK;
}

/* no Integer, Boolean or String variables: only empty requests succeed */
#define NO_VARS(NAME, T, CONST)                                                              \
    fmi2Status NAME(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, CONST T value[]) \
    {                                                                                        \
        (void)vr; (void)value;                                                               \
        if (bad(c, #NAME, ALL_STATES)) return fmi2Error;                                     \
        if (nvr == 0) return fmi2OK;                                                         \
        logf_((Instance *)c, fmi2Error, "logStatusError",                                    \
              #NAME ": unknown value reference %u (LinearBearing has Real variables only)",  \
              vr ? vr[0] : 0u);                                                              \
        return fmi2Error;                                                                    \
    }

#ifdef MISBEHAVING
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    Instance *inst = (Instance *)c;
    size_t i;
    if (bad(c, "fmi2GetInteger", ALL_STATES)) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (vr[i] != VR_FAULT && vr[i] != VR_FAULT_STEP) {
            logf_(inst, fmi2Error, "logStatusError", "fmi2GetInteger: unknown value reference %u", vr[i]);
            return fmi2Error;
        }
        value[i] = vr[i] == VR_FAULT ? inst->fault : inst->fault_step;
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    Instance *inst = (Instance *)c;
    size_t i;
    if (bad(c, "fmi2SetInteger", ST_INSTANTIATED | ST_INITIALIZATION)) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (vr[i] == VR_FAULT) inst->fault = value[i];
        else if (vr[i] == VR_FAULT_STEP) inst->fault_step = value[i];
        else {
            logf_(inst, fmi2Error, "logStatusError", "fmi2SetInteger: unknown value reference %u", vr[i]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}
#else
NO_VARS(fmi2GetInteger, fmi2Integer, )
NO_VARS(fmi2SetInteger, fmi2Integer, const)
#endif
NO_VARS(fmi2GetBoolean, fmi2Boolean, )
NO_VARS(fmi2SetBoolean, fmi2Boolean, const)
NO_VARS(fmi2GetString, fmi2String, )
NO_VARS(fmi2SetString, fmi2String, const)

/* --------------------------------------------------------------- FMU state */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    Instance *inst = (Instance *)c;
    Data *s;
    if (bad(c, "fmi2GetFMUstate", ALL_STATES)) return fmi2Error;
    if (!FMUstate) return fail(inst, "fmi2GetFMUstate", "NULL argument");
#ifdef MISBEHAVING
    if (inst->fault == 13) return fmi2OK;            /* no state given, *FMUstate left as it is */
#endif
    s = (Data *)*FMUstate;
    if (!s) {
        s = (Data *)inst->cb.allocateMemory(1, sizeof(Data));
        if (!s) return fail(inst, "fmi2GetFMUstate", "out of memory");
        *FMUstate = s;
    }
    *s = inst->d;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    Instance *inst = (Instance *)c;
    if (bad(c, "fmi2SetFMUstate", ALL_STATES)) return fmi2Error;
    if (!FMUstate) return fail(inst, "fmi2SetFMUstate", "NULL state");
    inst->d = *(Data *)FMUstate;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    Instance *inst = (Instance *)c;
    if (bad(c, "fmi2FreeFMUstate", ALL_STATES)) return fmi2Error;
    if (!FMUstate) return fmi2OK;
    if (*FMUstate) inst->cb.freeMemory(*FMUstate);
    *FMUstate = NULL;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    (void)FMUstate;
    if (bad(c, "fmi2SerializedFMUstateSize", ALL_STATES)) return fmi2Error;
    if (!size) return fail((Instance *)c, "fmi2SerializedFMUstateSize", "NULL argument");
    *size = sizeof(Data);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size)
{
    if (bad(c, "fmi2SerializeFMUstate", ALL_STATES)) return fmi2Error;
    if (!FMUstate || !serializedState || size < sizeof(Data))
        return fail((Instance *)c, "fmi2SerializeFMUstate", "bad argument or buffer too small");
    memcpy(serializedState, FMUstate, sizeof(Data));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    Instance *inst = (Instance *)c;
    if (bad(c, "fmi2DeSerializeFMUstate", ALL_STATES)) return fmi2Error;
    if (!serializedState || !FMUstate || size != sizeof(Data))
        return fail(inst, "fmi2DeSerializeFMUstate", "bad argument or size (not a LinearBearing state)");
    if (!*FMUstate) {
        *FMUstate = inst->cb.allocateMemory(1, sizeof(Data));
        if (!*FMUstate) return fail(inst, "fmi2DeSerializeFMUstate", "out of memory");
    }
    memcpy(*FMUstate, serializedState, sizeof(Data));
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    if (!c) return fmi2Error;
    return fail((Instance *)c, "fmi2GetDirectionalDerivative", "not supported (providesDirectionalDerivative=false)");
}

/* ---------------------------------------------------------- co-simulation */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    if (!c) return fmi2Error;
    return fail((Instance *)c, "fmi2SetRealInputDerivatives", "not supported (canInterpolateInputs=false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    if (!c) return fmi2Error;
    return fail((Instance *)c, "fmi2GetRealOutputDerivatives", "not supported (maxOutputDerivativeOrder=0)");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Instance *inst = (Instance *)c;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (bad(c, "fmi2DoStep", ST_STEP_COMPLETE)) return fmi2Error;
    if (!(communicationStepSize > 0.0)) {
        logf_(inst, fmi2Error, "logStatusError", "fmi2DoStep: communicationStepSize must be > 0 (got %g)",
              communicationStepSize);
        return fmi2Error;
    }
    inst->d.time = currentCommunicationPoint + communicationStepSize;
    compute_outputs(&inst->d);
#ifdef MISBEHAVING
    inst->steps++;
    return misbehave(inst);
#else
    return fmi2OK;
#endif
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    if (!c) return fmi2Error;
    return fail((Instance *)c, "fmi2CancelStep", "not supported (fmi2DoStep never returns fmi2Pending)");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    (void)s; (void)value;
    if (!c) return fmi2Error;
    return fail((Instance *)c, "fmi2GetStatus", "not supported (synchronous FMU)");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    Instance *inst = (Instance *)c;
    if (!c) return fmi2Error;
    if (s == fmi2LastSuccessfulTime && value) {
        *value = inst->d.time;
        return fmi2OK;
    }
    return fail(inst, "fmi2GetRealStatus", "only fmi2LastSuccessfulTime is supported");
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    (void)s; (void)value;
    if (!c) return fmi2Error;
    return fail((Instance *)c, "fmi2GetIntegerStatus", "not supported");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    (void)s; (void)value;
    if (!c) return fmi2Error;
    return fail((Instance *)c, "fmi2GetBooleanStatus", "not supported");
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    (void)s; (void)value;
    if (!c) return fmi2Error;
    return fail((Instance *)c, "fmi2GetStringStatus", "not supported");
}

/* ------------------------------ Model Exchange functions (not provided) */

fmi2Status fmi2EnterEventMode(fmi2Component c) { return c ? fail((Instance *)c, "fmi2EnterEventMode", "co-simulation only") : fmi2Error; }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *e) { (void)e; return c ? fail((Instance *)c, "fmi2NewDiscreteStates", "co-simulation only") : fmi2Error; }
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { return c ? fail((Instance *)c, "fmi2EnterContinuousTimeMode", "co-simulation only") : fmi2Error; }
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean n, fmi2Boolean *e, fmi2Boolean *t) { (void)n; (void)e; (void)t; return c ? fail((Instance *)c, "fmi2CompletedIntegratorStep", "co-simulation only") : fmi2Error; }
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) { (void)t; return c ? fail((Instance *)c, "fmi2SetTime", "co-simulation only") : fmi2Error; }
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t n) { (void)x; (void)n; return c ? fail((Instance *)c, "fmi2SetContinuousStates", "co-simulation only") : fmi2Error; }
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real d[], size_t n) { (void)d; (void)n; return c ? fail((Instance *)c, "fmi2GetDerivatives", "co-simulation only") : fmi2Error; }
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real e[], size_t n) { (void)e; (void)n; return c ? fail((Instance *)c, "fmi2GetEventIndicators", "co-simulation only") : fmi2Error; }
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t n) { (void)x; (void)n; return c ? fail((Instance *)c, "fmi2GetContinuousStates", "co-simulation only") : fmi2Error; }
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t n) { (void)x; (void)n; return c ? fail((Instance *)c, "fmi2GetNominalsOfContinuousStates", "co-simulation only") : fmi2Error; }
