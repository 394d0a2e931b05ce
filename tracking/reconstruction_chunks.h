#pragma once
// Long clips in chunks (internal to reconstruction.cpp): a clip of more than chunk_frames frames
// is reconstructed a chunk at a time, each chunk starting with the last chunk_overlap frames of
// the one before, and each chained to the trajectory so far by the similarity of the frames they
// share. Memory is then that of one chunk whatever the clip's length, and time grows linearly
// with it; what is given up is a bundle adjustment across chunks (drift is not corrected, as
// nothing closes loops anyway).
#include <functional>

#include "capture/rig.h"
#include "capture/source.h"
#include "tracking/reconstruction.h"

namespace odvr::tracking {

using ReconstructPiece =
    std::function<Reconstruction(capture::Source& source, const ReconstructionCallbacks& callbacks)>;

// Reads `source` to its end (or options.max_frames) chunk by chunk, reconstructs each with
// `piece` and chains them. Throws odvr::Error when a chunk shares fewer than two posed frames with
// the one before (it cannot be placed).
Reconstruction ReconstructInChunks(capture::Source& source, const ReconstructionOptions& options,
                                   const ReconstructionCallbacks& callbacks, const ReconstructPiece& piece);

}  // namespace odvr::tracking
