// What the compiled core was linked against, for packaging checks (symbol isolation from the
// host's Embree: Blender exports Embree 4's rtc* symbols). Defined in src/embree_scene.cpp.
#pragma once
#include <string>

namespace bsgi {

// The version of the Embree library that rtc* calls actually reach, e.g. "3.13.5".
std::string embree_version();
// The file of the shared library that provides rtcNewDevice to this module ("" if unknown).
std::string embree_library();

}  // namespace bsgi
