// Verification runs (HACCP 9 CFR 417.4, plant.yaml `verification:`): how often each lane must
// show a declared test piece, and how closely.
#pragma once

namespace rangex {

struct VerificationConfig {
  double every_h = 0;  // a lane's verification is due this long after its last (0: no schedule)
  int fillets = 5;     // the piece must show within the lane's next this many fillets
  double tolerance_mm = 10;  // ... within this distance across the belt of where declared
};

}  // namespace rangex
