#pragma once
// Where the demo's media are: what `odvr` plays with no argument, and the car the live player
// stands in the street.
#include <string>

namespace odvr::app {

// media/demo/street.mp4 beside the sources (a build tree) or in the working directory; throws
// odvr::Error naming it if neither holds it.
std::string DefaultDemoVideo();

}  // namespace odvr::app
