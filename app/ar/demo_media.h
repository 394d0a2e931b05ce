#pragma once
// Where the demo's media are: what `odvr` plays with no argument, and the car the live player
// stands in the street.
#include <string>

namespace odvr::app {

// The clip `odvr` plays with no argument, beside the sources (a build tree) or in the working
// directory: media/drive/street.mp4 (the 10 s drive at 2048×1024) where it is, else
// media/demo/street.mp4 (the rig's 1 s street, which the tests play). Each folder holds the
// clip's trajectory_gt.json and car.glb beside it. Throws odvr::Error naming the clip if neither
// is there.
std::string DefaultDemoVideo();

}  // namespace odvr::app
