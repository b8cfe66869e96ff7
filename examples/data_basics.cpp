// Data basics: read a 1 kHz throttle recording, decimate it to 100 Hz with the anti-alias filter,
// remove the 15° rest offset, and look at what happened to it.
#include <cstdio>
#include <filesystem>

#include "nlid/data.hpp"

int main() {
  // Columns t, u, y; the sample time (1 ms) is inferred from the time column and checked.
  const nlid::Experiment raw = nlid::read_csv(NLID_EXAMPLE_DATA_DIR "/throttle/data1.csv");
  std::printf("raw:       %ld samples, ts = %g s, y in [%.2f, %.2f] deg\n",
              static_cast<long>(raw.size()), raw.ts(), raw.y().minCoeff(), raw.y().maxCoeff());

  // Zero-phase Chebyshev low-pass at 40 Hz, then every 10th sample: 100 Hz, as in the study.
  const nlid::Experiment slow = nlid::decimate(raw, 10);
  std::printf("decimated: %ld samples, ts = %g s, y in [%.2f, %.2f] deg\n",
              static_cast<long>(slow.size()), slow.ts(), slow.y().minCoeff(), slow.y().maxCoeff());

  // A linear model describes deviations from the rest position: remove the 15° offset.
  const nlid::Experiment lin = nlid::remove_offset(slow, 0.0, 15.0);
  std::printf("offset removed: mean y = %.3f deg\n", lin.y().mean());

  // Everything that changed the samples is in the record's history.
  for (const auto& note : lin.notes()) std::printf("  - %s\n", note.c_str());

  // Save it (atomically, full precision) for another tool.
  const auto out = std::filesystem::temp_directory_path() / "data1_100Hz.csv";
  nlid::write_csv(out.string(), lin);
  std::printf("written to %s\n", out.c_str());
  return 0;
}
