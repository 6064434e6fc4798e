// SPDX-License-Identifier: Apache-2.0
// The pipeline's stages in the order they run on every batch of frames. Each line names a
// factory `make<Name>Stage(Model&)` defined in src/pipeline/stages/ (which returns null when
// the settings leave the stage out). Adding a stage: one new file there and one line here.
DS_STAGE(Align)        // rigid fit of each driver frame to the rest driver (align.cpp)
DS_STAGE(Project)      // M^T (b - m) per frame and weight problem (project.cpp)
DS_STAGE(Weights)      // the QP, or a baseline's weights (weights.cpp)
DS_STAGE(Pose)         // the pose model's weights and coverage figures (pose.cpp)
DS_STAGE(Blend)        // the database shapes blended with the weights (blend.cpp)
DS_STAGE(Correct)      // onto the shot's driver: rebuild or bind-and-transfer (correct.cpp)
DS_STAGE(BlendAudit)   // inside count of the world blend, before correction (blend_audit.cpp)
DS_STAGE(StrainLimit)  // edges back into a band around their rest lengths (strain_limit.cpp)
DS_STAGE(Resolve)      // cloth out of the body to the skin offset (resolve.cpp)
DS_STAGE(Settle)       // with the strain limit: shallow cloth left inside just out (settle.cpp)
DS_STAGE(Layers)       // mix with another cache, wind (layers.cpp)
DS_STAGE(Audit)        // inside counts, binding switches, jumps (audit.cpp)
