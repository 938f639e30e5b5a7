/* A plain C co-simulation host: dlopen an FMU's binary, call the FMI 2.0 functions, print
   "t v0 v1 ..." after each communication step. No Python is loaded.
   usage: cs_host BINARY GUID STOP STEP TOL VR...   (the unzipped FMU's binary; value references) */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...)
{
    va_list args;
    (void)env; (void)category;
    va_start(args, message);
    fprintf(stderr, "%s (status %d): ", name, (int)status);
    vfprintf(stderr, message, args);
    fprintf(stderr, "\n");
    va_end(args);
}

#define GET(type, name) type name = (type)dlsym(lib, #name); if (!name) { fprintf(stderr, "no %s\n", #name); return 3; }

int main(int argc, char **argv)
{
    void *lib;
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c;
    double stop, step, tol, t = 0.0, values[64];
    fmi2ValueReference vr[64];
    int n = argc - 6, i;
    long k;
    if (argc < 7 || n > 64) { fprintf(stderr, "usage: cs_host BINARY GUID STOP STEP TOL VR...\n"); return 2; }
    stop = atof(argv[3]); step = atof(argv[4]); tol = atof(argv[5]);
    for (i = 0; i < n; i++) vr[i] = (fmi2ValueReference)atol(argv[6 + i]);
    lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 3; }
    {
        GET(fmi2InstantiateTYPE *, fmi2Instantiate)
        GET(fmi2SetupExperimentTYPE *, fmi2SetupExperiment)
        GET(fmi2EnterInitializationModeTYPE *, fmi2EnterInitializationMode)
        GET(fmi2ExitInitializationModeTYPE *, fmi2ExitInitializationMode)
        GET(fmi2DoStepTYPE *, fmi2DoStep)
        GET(fmi2GetRealTYPE *, fmi2GetReal)
        GET(fmi2TerminateTYPE *, fmi2Terminate)
        GET(fmi2FreeInstanceTYPE *, fmi2FreeInstance)
        c = fmi2Instantiate("host", fmi2CoSimulation, argv[2], "", &cb, fmi2False, fmi2False);
        if (!c) return 4;
        if (fmi2SetupExperiment(c, fmi2True, tol, 0.0, fmi2True, stop) != fmi2OK) return 5;
        if (fmi2EnterInitializationMode(c) != fmi2OK || fmi2ExitInitializationMode(c) != fmi2OK) return 5;
        for (k = 0;; k++) {
            if (fmi2GetReal(c, vr, (size_t)n, values) != fmi2OK) return 6;
            printf("%.17g", t);
            for (i = 0; i < n; i++) printf(" %.17g", values[i]);
            printf("\n");
            if (t >= stop - 1e-9 * step) break;
            if (fmi2DoStep(c, t, step, fmi2True) != fmi2OK) return 7;
            t = (k + 1) * step;
        }
        fmi2Terminate(c);
        fmi2FreeInstance(c);
    }
    dlclose(lib);
    return 0;
}
