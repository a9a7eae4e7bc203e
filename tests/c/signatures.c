/* Compile-time check of the C ABI: the official FMI 2.0 headers and ours declare the same
 * functions, so any difference in a signature is a "conflicting types" error, and every one of
 * our functions is assigned to the standard's function-pointer type.
 * Built by tests/c_abi.rs with: cc -std=c99 -Wall -Wextra -Werror -pedantic -c. */
#include "fmi2Functions.h"
#include "mps_fmi.h"

#define CHECK(name) name##TYPE *const check_##name = &name;

/* Common functions. */
CHECK(fmi2GetTypesPlatform)
CHECK(fmi2GetVersion)
CHECK(fmi2SetDebugLogging)
CHECK(fmi2Instantiate)
CHECK(fmi2FreeInstance)
CHECK(fmi2SetupExperiment)
CHECK(fmi2EnterInitializationMode)
CHECK(fmi2ExitInitializationMode)
CHECK(fmi2Terminate)
CHECK(fmi2Reset)
CHECK(fmi2GetReal)
CHECK(fmi2GetInteger)
CHECK(fmi2GetBoolean)
CHECK(fmi2GetString)
CHECK(fmi2SetReal)
CHECK(fmi2SetInteger)
CHECK(fmi2SetBoolean)
CHECK(fmi2SetString)
CHECK(fmi2GetFMUstate)
CHECK(fmi2SetFMUstate)
CHECK(fmi2FreeFMUstate)
CHECK(fmi2SerializedFMUstateSize)
CHECK(fmi2SerializeFMUstate)
CHECK(fmi2DeSerializeFMUstate)
CHECK(fmi2GetDirectionalDerivative)

/* Co-simulation functions. */
CHECK(fmi2SetRealInputDerivatives)
CHECK(fmi2GetRealOutputDerivatives)
CHECK(fmi2DoStep)
CHECK(fmi2CancelStep)
CHECK(fmi2GetStatus)
CHECK(fmi2GetRealStatus)
CHECK(fmi2GetIntegerStatus)
CHECK(fmi2GetBooleanStatus)
CHECK(fmi2GetStringStatus)

/* The platform our header was written for. */
typedef char check_platform[sizeof(fmi2TypesPlatform) == sizeof("default") ? 1 : -1];
