//! The paper's case 3 (cube hitting a block, contact and fracture): scene builders and reports (work in progress).
