//! The IK's hot path allocates nothing: FK, frame Jacobians, CoM and CoM Jacobian run with a
//! counting global allocator and must leave its count unchanged.

use nalgebra::{Matrix3xX, Matrix6xX};
use stairbench::robot::{hrp4, Kinematics};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator, only counting calls.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn kinematics_hot_path_does_not_allocate() {
    let model = hrp4::model().unwrap();
    let joints = hrp4::half_sitting_joints(&model).unwrap();
    let q = hrp4::standing_config(&model, &joints, &nalgebra::Isometry3::identity()).unwrap();
    let mut k = Kinematics::new(&model);
    let mut jac = Matrix6xX::zeros(model.nv());
    let mut jcom = Matrix3xX::zeros(model.nv());
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    for _ in 0..10 {
        k.update(&q).unwrap();
        for f in 0..model.frames().len() {
            k.frame_jacobian_into(f, &mut jac);
        }
        std::hint::black_box(k.com());
        k.com_jacobian_into(&mut jcom);
    }
    let after = ALLOCATIONS.load(Ordering::SeqCst);
    assert_eq!(after - before, 0, "the hot path allocated {} times", after - before);
    assert!(jcom.iter().any(|x| *x != 0.0), "the work was done");
}
