// A dual-energy line detector of the sandwich kind (as food X-ray machines use: Ishida's
// IX-G2, Detection Technology's X-Scan DE): a thin scintillator layer that takes the soft
// part of the beam (low energy), a copper filter, and a thicker layer behind it (high
// energy), each an energy-integrating line. The tube's spectrum is Kramers' law for a
// tungsten anode, (kVp - E) / E photons per keV, through its aluminium filtration (the
// characteristic lines are left out). Attenuations are xray_materials.h's.
#pragma once
#include <functional>
#include <vector>

namespace rangex {

struct SandwichDetector {
  double kvp = 80;                 // tube voltage, kV
  double tube_filter_al_mm = 2.5;  // the tube's own and added filtration
  double front_csi_mm = 0.15;      // the low-energy layer
  double filter_cu_mm = 0.4;       // between the layers
  double back_csi_mm = 0.8;        // the high-energy layer
  // The dose: photons the low layer absorbs per pixel and line from the open beam (the tube's
  // current over a line's integration time). The simulator draws its noise from it; the
  // pipeline measures the noise it gets from the wedge and the counts themselves.
  double low_photons = 40000;
};

// Per 1 keV bin (centres from 15.5 keV to kVp), the photons each layer absorbs from the
// open beam, as shares (each layer's sum is 1); a layer's signal is the energy it absorbs
// (sum of photons x keV), its variance the sum of photons x keV^2 (energy-integrating noise).
struct LayerSpectra {
  std::vector<double> kev;
  std::vector<double> low, high;    // photon shares per bin
  double high_photons_per_low = 0;  // photons the high layer absorbs per photon of the low one
  double low_mean_kev = 0, high_mean_kev = 0;  // signal-weighted mean energies
};

LayerSpectra layer_spectra(const SandwichDetector& d);

// ln(open / I) of each layer, noiseless, for a ray whose attenuation at E keV is att(E)
// (the sum of mu x length over what it crosses).
void layer_log_attenuations(const LayerSpectra& s, const std::function<double(double)>& att,
                            double* low, double* high);

}  // namespace rangex
