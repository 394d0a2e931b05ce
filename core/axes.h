#pragma once
// The datasets' and Blender's Z-up world (x forward, y left, z up) to odvr's Y-up one (forward +X,
// up +Y, right +Z): (x, y, z) -> (x, z, -y), the frame engine/sphere/equirect.h defines. Rows of
// the matrix C, so p_yup = C p_zup; C is a rotation, C^-1 = C^T.

namespace odvr {

inline constexpr double kYupFromZup[3][3] = {{1, 0, 0}, {0, 0, 1}, {0, -1, 0}};

}  // namespace odvr
