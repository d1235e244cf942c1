#include "lookup/obs/register_classes.h"

#include <mrpt/core/initializer.h>
#include <mrpt/rtti/CObject.h>

#include "lookup/obs/observation_lookup_reference.h"
#include "lookup/obs/observation_lookup_result.h"

namespace lookup::obs {

void registerClasses() {
    // registerClass() ignores duplicates, so this may run any number of times.
    mrpt::rtti::registerClass(CLASS_ID(CObservationLookupReference));
    mrpt::rtti::registerClass(CLASS_ID(CObservationLookupResult));
}

}  // namespace lookup::obs

// Runs when the shared library is loaded: by the dynamic linker for programs linking it, or by
// dlopen() for RawLogViewer -l / mrpt::system::loadPluginModule().
MRPT_INITIALIZER(registerAllClasses_lookup_obs) { lookup::obs::registerClasses(); }
