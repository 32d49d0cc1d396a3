//! The module's face for the page: plain `extern "C"` functions over one scene held by the
//! module, the playground or the pile ([`sf_scene`]; the playground until told otherwise).
//! Numbers go in as arguments; what the page draws or reads (the render buffer, the indices, the
//! statistics, the colliders, the last error's text) stays in the module's memory, and a
//! function returns where it starts, for the page to view through typed arrays (views to take
//! again after every call: the memory may grow).
//!
//! No export panics: every failure is a status code, with the text of the last one at
//! [`sf_error_ptr`] ([`sf_error_len`] bytes of UTF-8). Status codes: 0 success, 1 a material
//! parameter refused, 2 a body refused its mesh, solver or a vertex, 3 a step failed (the scene
//! stays as before that body's step; restart or change a setting), 4 a frame time not finite
//! and positive, 5 a model, stepper or scene code out of range, 6 no scene (the first
//! [`sf_restart`] failed), 7 a call made while another was running (not possible from one
//! JavaScript thread).

use core::cell::RefCell;
use core::fmt::Write;

use softfem::glam::Vec3;

use crate::scene::{Model, SceneError, Settings, Stepper, collider_record};
use crate::stage::{Kind, Stage};

/// The numbers [`sf_stats`] writes, in this order.
pub const STATS: [&str; 17] = [
    "steps",
    "time",
    "tets",
    "vertices",
    "converged share",
    "kinetic energy",
    "gravitational energy",
    "elastic energy",
    "finite",
    "grabbing",
    "error code",
    "grab x",
    "grab y",
    "grab z",
    "bodies",
    "contact pairs",
    "scene",
];

/// Numbers per collider in [`sf_colliders`] (see [`collider_record`]).
pub const COLLIDER_LEN: usize = 11;

#[derive(Default)]
struct State {
    stage: Option<Stage>,
    /// The scene [`sf_restart`] builds.
    kind: Kind,
    settings: Settings,
    error: String,
    code: i32,
    stats: [f64; STATS.len()],
    grabbed: [f64; 3],
    colliders: Vec<f32>,
    settings_out: [f32; 5],
}

thread_local! {
    static STATE: RefCell<State> = RefCell::new(State::default());
}

/// Runs `f` on the state; 7 if it is already borrowed or gone.
fn with_state<R>(fallback: R, f: impl FnOnce(&mut State) -> R) -> R {
    STATE
        .try_with(|state| match state.try_borrow_mut() {
            Ok(mut state) => Some(f(&mut state)),
            Err(_) => None,
        })
        .ok()
        .flatten()
        .unwrap_or(fallback)
}

fn code_of(error: &SceneError) -> i32 {
    match error {
        SceneError::Material(_) => 1,
        SceneError::Body(_) => 2,
        SceneError::Step { .. } => 3,
        SceneError::FrameTime(_) => 4,
        SceneError::Code(_) => 5,
    }
}

impl State {
    /// Records the outcome: 0, or the error's code with its text.
    fn outcome(&mut self, result: Result<(), SceneError>) -> i32 {
        match result {
            Ok(()) => 0,
            Err(error) => self.fail(code_of(&error), format_args!("{error}")),
        }
    }

    fn fail(&mut self, code: i32, text: core::fmt::Arguments<'_>) -> i32 {
        self.code = code;
        self.error.clear();
        // Writing to a String cannot fail.
        self.error.write_fmt(text).ok();
        code
    }

    /// Builds a scene of `kind` with `settings` (as the kind admits them).
    fn restart(&mut self) -> i32 {
        self.code = 0;
        self.error.clear();
        self.settings = self.kind.admitted(self.settings);
        match Stage::new(self.kind, self.settings) {
            Ok(stage) => {
                self.stage = Some(stage);
                0
            }
            Err(error) => self.outcome(Err(error)),
        }
    }

    fn no_scene(&mut self) -> i32 {
        self.fail(6, format_args!("no scene: restart it"))
    }
}

/// Builds the scene at `t = 0` with the settings last given to [`sf_configure`], or, if
/// `defaults` is not 0, with [`Settings::default`] (also before any [`sf_configure`]); the pile
/// takes Newton's method where the settings say Vertex Block Descent ([`Kind::admitted`]).
/// Returns the status (0 or 1, 2, 4 with the error's text).
#[unsafe(no_mangle)]
pub extern "C" fn sf_restart(defaults: u32) -> i32 {
    with_state(7, |state| {
        if defaults != 0 {
            state.settings = Settings::default();
        }
        state.restart()
    })
}

/// Switches to the scene numbered `kind` (0 the playground, 1 the pile) and builds it at `t = 0`
/// as [`sf_restart`]`(0)` does. Returns the status (5 for a number out of range: nothing
/// changes then).
#[unsafe(no_mangle)]
pub extern "C" fn sf_scene(kind: u32) -> i32 {
    with_state(7, |state| match Kind::from_code(kind) {
        Some(kind) => {
            state.kind = kind;
            state.restart()
        }
        None => state.outcome(Err(SceneError::Code(kind))),
    })
}

/// Sets the model (0 StVK, 1 Neo-Hookean, 2 Stable Neo-Hookean), the stepper (0 explicit,
/// 1 relaxation, 2 Newton, 3 Vertex Block Descent), Young's modulus of the box (Pa; the
/// playground's balls 0.6 and 3 times it, the pile's balls twice it), Poisson's ratio and the
/// frame time (s), on the running scene (see [`Stage::configure`]; the pile refuses Vertex Block
/// Descent with status 2). Returns the status; on error nothing changes.
#[unsafe(no_mangle)]
pub extern "C" fn sf_configure(
    model: u32,
    stepper: u32,
    young: f32,
    poisson: f32,
    frame_time: f32,
) -> i32 {
    with_state(7, |state| {
        let (Some(model), Some(stepper)) = (Model::from_code(model), Stepper::from_code(stepper))
        else {
            let code = if Model::from_code(model).is_none() {
                model
            } else {
                stepper
            };
            return state.outcome(Err(SceneError::Code(code)));
        };
        let settings = Settings {
            model,
            young,
            poisson,
            stepper,
            frame_time,
        };
        let result = match state.stage.as_mut() {
            Some(stage) => stage.configure(settings),
            None => Stage::new(state.kind, settings).map(|p| state.stage = Some(p)),
        };
        if result.is_ok() {
            state.settings = settings;
            state.code = 0;
            state.error.clear();
        }
        state.outcome(result)
    })
}

/// Writes the settings in force (model code, stepper code, Young's modulus of the box in Pa,
/// Poisson's ratio, frame time in s; five f32) and returns where they start.
#[unsafe(no_mangle)]
pub extern "C" fn sf_settings() -> *const f32 {
    with_state(core::ptr::null(), |state| {
        let s = state.settings;
        let model = match s.model {
            Model::StVK => 0.0,
            Model::NeoHookean => 1.0,
            Model::StableNeoHookean => 2.0,
        };
        let stepper = match s.stepper {
            Stepper::Explicit => 0.0,
            Stepper::Relax => 1.0,
            Stepper::Newton => 2.0,
            Stepper::Vbd => 3.0,
        };
        state.settings_out = [model, stepper, s.young, s.poisson, s.frame_time];
        state.settings_out.as_ptr()
    })
}

/// One step of the frame time (see [`Stage::step`]). Returns the status.
#[unsafe(no_mangle)]
pub extern "C" fn sf_step() -> i32 {
    with_state(7, |state| match state.stage.as_mut() {
        Some(stage) => {
            let result = stage.step();
            state.outcome(result)
        }
        None => state.no_scene(),
    })
}

/// Recomputes the render buffer from the bodies' positions (see [`Stage::update_render`]).
#[unsafe(no_mangle)]
pub extern "C" fn sf_update_render() {
    with_state((), |state| {
        if let Some(stage) = state.stage.as_mut() {
            stage.update_render();
        }
    });
}

/// Grabs the body vertex nearest the camera within reach of the ray from `o` along `d` (m; see
/// [`Stage::grab`]). Returns 1 if a body was grabbed (its point is in the statistics),
/// 0 if not.
#[unsafe(no_mangle)]
pub extern "C" fn sf_grab(ox: f32, oy: f32, oz: f32, dx: f32, dy: f32, dz: f32) -> i32 {
    with_state(0, |state| {
        let picked = state
            .stage
            .as_mut()
            .and_then(|p| p.grab(Vec3::new(ox, oy, oz), Vec3::new(dx, dy, dz)));
        match picked {
            Some(point) => {
                state.grabbed = point.to_array().map(f64::from);
                1
            }
            None => 0,
        }
    })
}

/// Where the pointer wants the grabbed point (m).
#[unsafe(no_mangle)]
pub extern "C" fn sf_drag(x: f32, y: f32, z: f32) {
    with_state((), |state| {
        if let Some(stage) = state.stage.as_mut() {
            stage.drag(Vec3::new(x, y, z));
        }
    });
}

/// Lets go of the grabbed body.
#[unsafe(no_mangle)]
pub extern "C" fn sf_release() {
    with_state((), |state| {
        if let Some(stage) = state.stage.as_mut() {
            stage.release();
        }
    });
}

/// Fills the statistics ([`STATS`], f64 each) and returns where they start (null if the state
/// cannot be reached).
#[unsafe(no_mangle)]
pub extern "C" fn sf_stats() -> *const f64 {
    with_state(core::ptr::null(), |state| {
        fill_stats(state);
        state.stats.as_ptr()
    })
}

fn fill_stats(state: &mut State) {
    let mut stats = [0.0; STATS.len()];
    if let Some(p) = state.stage.as_ref() {
        let energy = p.energy();
        let [gx, gy, gz] = state.grabbed;
        stats = [
            p.steps() as f64,
            p.time(),
            p.tet_count() as f64,
            p.vertex_count() as f64,
            p.converged_share(),
            energy.kinetic,
            energy.gravity,
            energy.elastic,
            f64::from(u8::from(p.finite())),
            f64::from(u8::from(p.grabbing())),
            f64::from(state.code),
            gx,
            gy,
            gz,
            p.layout().len() as f64,
            p.contact_pairs() as f64,
            match p.kind() {
                Kind::Playground => 0.0,
                Kind::Pile => 1.0,
            },
        ];
    } else if let Some(code) = stats.get_mut(10) {
        *code = f64::from(state.code);
    }
    state.stats = stats;
}

/// Where the render buffer starts: per vertex of every body, position (m) and unit normal,
/// six f32.
#[unsafe(no_mangle)]
pub extern "C" fn sf_render_ptr() -> *const f32 {
    with_state(core::ptr::null(), |state| {
        state
            .stage
            .as_ref()
            .map_or(core::ptr::null(), |p| p.render().as_ptr().cast())
    })
}

/// The render buffer's vertex count (six f32 each).
#[unsafe(no_mangle)]
pub extern "C" fn sf_render_len() -> u32 {
    with_state(0, |state| {
        state.stage.as_ref().map_or(0, |p| p.render().len() as u32)
    })
}

/// Where the triangle indices into the render buffer start (u32, three per triangle,
/// counter-clockwise seen from outside).
#[unsafe(no_mangle)]
pub extern "C" fn sf_index_ptr() -> *const u32 {
    with_state(core::ptr::null(), |state| {
        state
            .stage
            .as_ref()
            .map_or(core::ptr::null(), |p| p.indices().as_ptr())
    })
}

/// The number of triangle indices.
#[unsafe(no_mangle)]
pub extern "C" fn sf_index_len() -> u32 {
    with_state(0, |state| {
        state.stage.as_ref().map_or(0, |p| p.indices().len() as u32)
    })
}

/// Where the bodies' layout starts: per body, four u32 (first render vertex, vertex count,
/// first index, index count); as many bodies as the statistics say.
#[unsafe(no_mangle)]
pub extern "C" fn sf_layout_ptr() -> *const u32 {
    with_state(core::ptr::null(), |state| {
        state
            .stage
            .as_ref()
            .map_or(core::ptr::null(), |p| p.layout().as_ptr().cast())
    })
}

/// Fills the colliders' records ([`COLLIDER_LEN`] f32 each, see [`collider_record`]) as they
/// are now and returns where they start.
#[unsafe(no_mangle)]
pub extern "C" fn sf_colliders() -> *const f32 {
    with_state(core::ptr::null(), |state| {
        state.colliders.clear();
        if let Some(p) = state.stage.as_ref() {
            state
                .colliders
                .extend(p.colliders().iter().flat_map(collider_record));
        }
        state.colliders.as_ptr()
    })
}

/// The number of colliders in [`sf_colliders`].
#[unsafe(no_mangle)]
pub extern "C" fn sf_collider_count() -> u32 {
    with_state(0, |state| {
        state
            .stage
            .as_ref()
            .map_or(0, |p| p.colliders().len() as u32)
    })
}

/// [`Stage::position_digest`] of the scene (0 without one).
#[unsafe(no_mangle)]
pub extern "C" fn sf_digest() -> u64 {
    with_state(0, |state| {
        state.stage.as_ref().map_or(0, Stage::position_digest)
    })
}

/// The SIMD width softfem's batched kernels run at (`softfem::simd::Width` as a number): 0 one
/// value at a time, which is what wasm32 gets (`softfem::simd::detected_width`), 1 groups of
/// four.
#[unsafe(no_mangle)]
pub extern "C" fn sf_simd_width() -> u32 {
    softfem::simd::active_width() as u32
}

/// Where the last error's text starts (UTF-8).
#[unsafe(no_mangle)]
pub extern "C" fn sf_error_ptr() -> *const u8 {
    with_state(core::ptr::null(), |state| state.error.as_ptr())
}

/// The length of the last error's text in bytes (0: no error).
#[unsafe(no_mangle)]
pub extern "C" fn sf_error_len() -> u32 {
    with_state(0, |state| state.error.len() as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn error_text() -> String {
        with_state(String::new(), |state| state.error.clone())
    }

    /// The exports' status codes and error texts; each test thread has its own state.
    #[test]
    fn exports_report_errors_as_codes_and_text() {
        assert_eq!(sf_step(), 6);
        assert!(error_text().contains("no scene"));
        assert!(sf_render_ptr().is_null() && sf_render_len() == 0);
        assert_eq!(sf_restart(1), 0);
        assert_eq!(sf_configure(9, 0, 5e4, 0.4, 0.01), 5);
        assert!(error_text().contains('9'), "{}", error_text());
        assert_eq!(sf_configure(2, 0, 5e4, 0.5, 0.01), 1);
        assert_eq!(sf_configure(2, 0, 5e4, 0.4, f32::NAN), 4);
        assert_eq!(sf_configure(2, 3, 5e4, 0.4, 0.01), 0);
        assert_eq!(sf_error_len(), 0);
        assert_eq!(sf_step(), 0);
        let stats = with_state([0.0; STATS.len()], |state| {
            fill_stats(state);
            state.stats
        });
        assert_eq!(stats[0], 1.0); // steps
        assert_eq!(stats[2], 2520.0); // tets: 1080 + 360 + 1080
        assert_eq!(stats[3], 826.0); // vertices: 343 + 140 + 343
        assert_eq!(stats[8], 1.0); // finite
        assert_eq!(stats[10], 0.0); // no error
        assert_eq!(sf_render_len(), 826);
        assert_eq!(sf_collider_count(), 4);
        assert_eq!(sf_grab(9.0, 9.0, 9.0, 0.0, 0.0, 1.0), 0);
    }

    fn stats() -> [f64; STATS.len()] {
        with_state([0.0; STATS.len()], |state| {
            fill_stats(state);
            state.stats
        })
    }

    /// Switching scenes: the pile takes Newton for the default VBD, refuses VBD while it runs,
    /// and the playground comes back with the settings in force.
    #[test]
    fn the_scene_switches_between_the_playground_and_the_pile() {
        assert_eq!(sf_restart(1), 0);
        assert_eq!(stats()[16], 0.0); // the playground
        assert_eq!(sf_scene(2), 5);
        assert!(error_text().contains('2'), "{}", error_text());
        assert_eq!(stats()[16], 0.0);
        assert_eq!(sf_scene(1), 0);
        let s = stats();
        assert_eq!((s[16], s[14], s[2], s[3]), (1.0, 6.0, 240.0, 162.0));
        let stepper = with_state(Stepper::Vbd, |state| state.settings.stepper);
        assert_eq!(stepper, Stepper::Newton);
        assert_eq!(sf_collider_count(), 5); // the ground and four walls
        assert_eq!(sf_configure(2, 3, 5e4, 0.4, 0.01), 2);
        assert!(error_text().contains("VBD"), "{}", error_text());
        assert_eq!(sf_configure(2, 2, 5e4, 0.4, 1.0 / 60.0), 0);
        assert_eq!(sf_step(), 0);
        assert_eq!(stats()[0], 1.0);
        assert_eq!(sf_restart(1), 0);
        assert_eq!((stats()[0], stats()[16]), (0.0, 1.0));
        assert_eq!(sf_scene(0), 0);
        let s = stats();
        assert_eq!((s[16], s[2], s[15]), (0.0, 2520.0, 0.0));
    }
}
