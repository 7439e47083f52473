#include "medium.h"

#include <limits>

namespace pgi {

void DensityGrid::build_majorants(int cell_size) {
    cell = std::max(1, cell_size);
    mx = (nx + cell - 1) / cell;
    my = (ny + cell - 1) / cell;
    mz = (nz + cell - 1) / cell;
    majorants.assign(size_t(mx) * my * mz, 0.0f);
    minorants.assign(size_t(mx) * my * mz, 0.0f);
    // Cell c spans voxel coordinates [c * cell, (c + 1) * cell) * (res / (m * cell));
    // trilinear lookups there read voxels floor(u - 0.5) .. floor(u - 0.5) + 1.
    auto voxel_range = [](int c, int m, int n, int &lo, int &hi) {
        double u0 = double(c) / m * n, u1 = double(c + 1) / m * n;
        lo = std::max(0, int(std::floor(u0 - 0.5)));
        hi = std::min(n - 1, int(std::floor(u1 - 0.5)) + 1);
    };
    for (int cz = 0; cz < mz; ++cz)
        for (int cy = 0; cy < my; ++cy)
            for (int cx = 0; cx < mx; ++cx) {
                int x0, x1, y0, y1, z0, z1;
                voxel_range(cx, mx, nx, x0, x1);
                voxel_range(cy, my, ny, y0, y1);
                voxel_range(cz, mz, nz, z0, z1);
                float hi = 0, lo = std::numeric_limits<float>::max();
                for (int z = z0; z <= z1; ++z)
                    for (int y = y0; y <= y1; ++y)
                        for (int x = x0; x <= x1; ++x) {
                            float v = values[(size_t(z) * ny + y) * nx + x];
                            hi = std::max(hi, v);
                            lo = std::min(lo, v);
                        }
                // Interpolated values are convex combinations of these voxels; small
                // margins keep float rounding of the interpolation inside the bounds.
                size_t index = (size_t(cz) * my + cy) * mx + cx;
                // A constant cell keeps exact bounds: residual tracking is then free there.
                majorants[index] = lo == hi ? hi : hi * 1.0001f;
                minorants[index] = lo == hi ? lo : std::max(0.0f, lo * 0.9999f);
            }
}

}  // namespace pgi
