//! Rigid colliders (`step::Collider`) for every stepper, in both precisions, asserted against
//! closed forms: resting contact on each shape with a bounded penetration, a block on an incline
//! (a half-space or the ground) that sticks when `tan(theta) < mu`, creeping by the closed form
//! of the implicit solvers' smoothed friction, and otherwise slides with the acceleration
//! `g (sin(theta) - mu cos(theta))` of Coulomb's law, a body carried by a moving surface at its
//! speed, a body dropped at 10 m/s onto each shape that never ends up inside it, and a kinematic
//! box that pushes a body along at its own speed.
//! The numeric runs are small (a 27-vertex cube) but many steps: unoptimised builds skip them
//! (`cargo test --release --test release colliders::` runs them, about 25 s here; `.ci/run` does).

mod single {
    use softfem as p;
    include!("colliders/suite.rs");
}

mod double {
    use softfem::f64 as p;
    include!("colliders/suite.rs");
}
