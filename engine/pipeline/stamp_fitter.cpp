// Per-thread batch fitting; see stamp_fitter.hpp.
#include "engine/pipeline/stamp_fitter.hpp"

#include <chrono>

namespace stampede {

StampFitter::StampFitter(const FitterOptions& options, std::shared_ptr<const PreparedPsf> shared_psf,
                         PsfCache* per_object, FftPlanning planning, double psf_e1, double psf_e2,
                         double psf_fwhm, std::optional<MetacalSetup> metacal)
    : options_(options),
      plans_(planning),
      fitter_(options, planning),
      shared_psf_(std::move(shared_psf)),
      per_object_(per_object),
      psf_e1_(psf_e1),
      psf_e2_(psf_e2),
      psf_fwhm_(psf_fwhm),
      metacal_(std::move(metacal)) {
  // A stamp's masked pixels weigh in metacal's fits as the rest (its row flagged unusable).
  if (metacal_)
    metacal_fitter_ = std::make_unique<MetacalFitter>(options_, metacal_->options, planning,
                                                      MetacalFitter::ImageWeight::kUniform);
}

void StampFitter::fit(StampBatch& batch) {
  for (int k = 0; k < batch.count; ++k) {
    ObjectRecord& rec = batch.records[k];
    const ArenaObservation& stamp = batch.observations.first_of(k);
    const auto t0 = std::chrono::steady_clock::now();
    std::uint32_t input_flags = rec.flags;
    Observation image = batch.observations.observation(stamp);
    rec.psf_e1 = psf_e1_;
    rec.psf_e2 = psf_e2_;
    rec.psf_fwhm = psf_fwhm_;
    if (per_object_) {
      if (!metacal_fitter_) {  // metacal fits with its reconvolution PSF, never this one
        std::string error;
        auto prepared = per_object_->get(stamp.psf, fitter_.renderer_for(stamp.box_size), &error);
        if (!prepared) input_flags |= kFlagPsfFailure;
        image.psf = std::move(prepared);
      }
      rec.psf_e1 = stamp.psf.e1();
      rec.psf_e2 = stamp.psf.e2();
      rec.psf_fwhm = stamp.psf.fwhm();
    }
    if (metacal_fitter_) {
      // A PSF metacal cannot use is every row's kPsfFailure; an object's own is also its flag.
      if (!per_object_) image.psf_model = &metacal_->shared_psf;
      metacal_problem_.clear();
      metacal_fitter_->fit({&image, 1}, rec.id, kFlagMetacalFailure, &rec.fit, &rec.metacal, &input_flags,
                           &metacal_problem_);
      if (per_object_ && rec.fit.status == FitStatus::kPsfFailure) input_flags |= kFlagPsfFailure;
    } else {
      if (!per_object_) image.psf = shared_psf_;
      rec.fit = fitter_.fit({&image, 1});
    }
    rec.flags = rec.fit.flags | input_flags;
    rec.time_us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
  }
}

}  // namespace stampede
