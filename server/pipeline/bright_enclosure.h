// How far a pixel lies sunk inside something bright. Fat attenuates less than lean meat, so
// a streak of it reads bright; the clip ahead of the whitened kernels holds it down to the
// texture's level, and with it a fragment lying inside the streak, whose bone takes back
// part of the fat's brightness but not all: clipped, fragment and streak read alike.
// A fragment in fat is a dip enclosed by the fat on every side; lean meat beside a streak,
// or between two streaks along the muscle, has lean meat on at least one line through it.
// So the level that encloses a pixel is taken along four lines (across, along, both
// diagonals) as the lower of the brightest pixel within `reach` on either side, and the
// lowest of the four: it fills a dip that bright pixels close within the reach on every
// line, and keeps whatever runs further than the reach along one. The CPU reference over
// flat row-major buffers.
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

namespace rangex {

// excess[i]: how far the level enclosing usable pixel i (within `reach` px on both sides of
// each of the four lines; unusable pixels enclose nothing) stands above `top`, 0 where it
// does not (or reach is 0); NaN off the usable pixels.
void bright_enclosure_excess(const float* z, const uint8_t* use, int rows, int cols, float top,
                             int reach, std::vector<float>& excess);

}  // namespace rangex
