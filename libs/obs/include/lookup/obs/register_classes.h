#pragma once
// Registration of the project's mrpt-rtti classes. Loading liblookup_obs.so registers them
// automatically (MRPT_INITIALIZER); calling this is harmless and makes the dependency explicit.

namespace lookup::obs {

/// Registers CObservationLookupReference and CObservationLookupResult with mrpt-rtti, so
/// rawlogs holding them can be read (and classFactory() knows their names).
void registerClasses();

}  // namespace lookup::obs
