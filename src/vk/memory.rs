//! The device-memory budget: how many bytes lancer's buffers may hold in
//! each memory heap, where that figure comes from, and which heap a buffer
//! lands in. Buffers are refused against the budget before the driver is
//! asked, so a scene too big for the device fails with a message that names
//! what did not fit, not with a driver error or, on lavapipe, whose heap is
//! system RAM, the out-of-memory killer.

use std::fmt;

use ash::vk;
use gpu_allocator::MemoryLocation;

use super::error::{VkError, VkResult};

/// The environment variable that replaces the device's budget, in bytes.
pub const BUDGET_ENV: &str = "LANCER_DEVICE_MEMORY_BUDGET";

/// Share of a heap's size, in percent, that lancer budgets when the device
/// lacks `VK_EXT_memory_budget`. The heap size is an upper bound that the
/// specification does not promise can be allocated (other processes, the
/// driver and, on a unified-memory device such as lavapipe, this process's
/// own host data share it). 80% is the figure AMD's Vulkan Memory Allocator
/// assumes in the same case.
pub const HEAP_SIZE_BUDGET_PERCENT: u64 = 80;

/// A memory heap as the device reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemoryHeap {
    /// `VkMemoryHeap::size`, in bytes.
    pub size: u64,
    /// Whether the heap is device local (`VK_MEMORY_HEAP_DEVICE_LOCAL_BIT`).
    pub device_local: bool,
    /// What `VK_EXT_memory_budget` reports for the heap, when the device
    /// has that extension.
    pub reported: Option<ReportedBudget>,
}

/// `VkPhysicalDeviceMemoryBudgetPropertiesEXT`'s figures for one heap.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReportedBudget {
    /// `heapBudget`: what the process can allocate from the heap in all,
    /// its current allocations included, in bytes.
    pub budget: u64,
    /// `heapUsage`: what is allocated from the heap now, in bytes.
    pub usage: u64,
}

/// Where a heap's budget came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BudgetSource {
    /// [`BUDGET_ENV`] set it.
    Environment,
    /// `VK_EXT_memory_budget`: `heapBudget` minus `heapUsage`, read when the
    /// device was opened.
    MemoryBudgetExt(ReportedBudget),
    /// [`HEAP_SIZE_BUDGET_PERCENT`] of the heap's size, for a device without
    /// `VK_EXT_memory_budget`.
    HeapSize(u64),
}

impl fmt::Display for BudgetSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BudgetSource::Environment => write!(f, "set by {BUDGET_ENV}"),
            BudgetSource::MemoryBudgetExt(r) => write!(
                f,
                "VK_EXT_memory_budget: heapBudget {} minus heapUsage {} bytes",
                r.budget, r.usage
            ),
            BudgetSource::HeapSize(size) => write!(
                f,
                "{HEAP_SIZE_BUDGET_PERCENT}% of the heap's {size} bytes; the device has no \
                 VK_EXT_memory_budget"
            ),
        }
    }
}

/// The bytes lancer's buffers may hold in one memory heap.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HeapBudget {
    /// The heap's index in `VkPhysicalDeviceMemoryProperties::memoryHeaps`.
    pub heap: u32,
    /// The budget, in bytes.
    pub bytes: u64,
    /// Where [`HeapBudget::bytes`] came from.
    pub source: BudgetSource,
}

/// The budget of every heap: `env` (from [`BUDGET_ENV`]) when given, else
/// what `VK_EXT_memory_budget` leaves free, else
/// [`HEAP_SIZE_BUDGET_PERCENT`] of the heap's size.
pub fn heap_budgets(heaps: &[MemoryHeap], env: Option<u64>) -> Vec<HeapBudget> {
    heaps
        .iter()
        .enumerate()
        .map(|(i, h)| {
            let (bytes, source) = match (env, h.reported) {
                (Some(bytes), _) => (bytes, BudgetSource::Environment),
                // A driver that reports no budget for a heap has not filled it in
                (None, Some(r)) if r.budget > 0 => (
                    r.budget.saturating_sub(r.usage),
                    BudgetSource::MemoryBudgetExt(r),
                ),
                (None, _) => (
                    (u128::from(h.size) * u128::from(HEAP_SIZE_BUDGET_PERCENT) / 100) as u64,
                    BudgetSource::HeapSize(h.size),
                ),
            };
            HeapBudget {
                heap: i as u32,
                bytes,
                source,
            }
        })
        .collect()
}

/// Reads [`BUDGET_ENV`]'s value: `None` when it is unset, else a whole
/// number of bytes of at least 1.
pub(crate) fn budget_from_env(value: Option<&str>) -> VkResult<Option<u64>> {
    let Some(text) = value else {
        return Ok(None);
    };
    match text.trim().parse::<u64>() {
        Ok(0) => Err(VkError::Usage(format!(
            "{BUDGET_ENV}=0 leaves no device memory at all; unset it to use the device's \
             budget, or give a number of bytes such as 1073741824 for 1 GiB"
        ))),
        Ok(bytes) => Ok(Some(bytes)),
        Err(_) => Err(VkError::Usage(format!(
            "{BUDGET_ENV}={:?} is not a number of bytes; unset it to use the device's budget, \
             or give a number of bytes such as 1073741824 for 1 GiB",
            crate::util::text::cut(text)
        ))),
    }
}

/// A memory type: its property flags and the heap it allocates from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct MemoryType {
    pub(crate) flags: vk::MemoryPropertyFlags,
    pub(crate) heap: u32,
}

/// The memory type gpu-allocator picks for a buffer at `location` that
/// accepts `type_bits`: the first type with the preferred flags, else the
/// first with the required ones (gpu-allocator's own order, so the budget
/// is charged to the heap the memory really comes from).
pub(crate) fn memory_type_for(
    types: &[MemoryType],
    type_bits: u32,
    location: MemoryLocation,
) -> Option<usize> {
    use vk::MemoryPropertyFlags as F;
    let (preferred, required) = match location {
        MemoryLocation::GpuOnly => (F::DEVICE_LOCAL, F::DEVICE_LOCAL),
        MemoryLocation::CpuToGpu => (
            F::HOST_VISIBLE | F::HOST_COHERENT | F::DEVICE_LOCAL,
            F::HOST_VISIBLE | F::HOST_COHERENT,
        ),
        MemoryLocation::GpuToCpu => (
            F::HOST_VISIBLE | F::HOST_COHERENT | F::HOST_CACHED,
            F::HOST_VISIBLE | F::HOST_COHERENT,
        ),
        _ => (F::empty(), F::empty()),
    };
    let find = |flags: F| {
        types
            .iter()
            .enumerate()
            .position(|(i, t)| type_bits & (1 << i) != 0 && t.flags.contains(flags))
    };
    find(preferred).or_else(|| find(required))
}

#[cfg(test)]
mod tests {
    use super::*;

    const GIB: u64 = 1 << 30;

    fn heap(size: u64, device_local: bool, reported: Option<(u64, u64)>) -> MemoryHeap {
        MemoryHeap {
            size,
            device_local,
            reported: reported.map(|(budget, usage)| ReportedBudget { budget, usage }),
        }
    }

    /// Without `VK_EXT_memory_budget` a heap's budget is 80% of its size;
    /// with it, heapBudget minus heapUsage; the variable overrides both.
    #[test]
    fn default_budget_is_what_the_device_reports() {
        // A discrete GPU: 8 GiB of VRAM and 32 GiB of host memory
        let discrete = [heap(8 * GIB, true, None), heap(32 * GIB, false, None)];
        let b = heap_budgets(&discrete, None);
        assert_eq!(b.len(), 2);
        assert_eq!(b[0].bytes, 6_871_947_673); // 80% of 8 GiB, rounded down
        assert_eq!(b[0].source, BudgetSource::HeapSize(8 * GIB));
        assert_eq!((b[1].heap, b[1].bytes), (1, 27_487_790_694));
        // The same GPU with the extension: budget 7 GiB, 1 GiB in use elsewhere
        let with_ext = [
            heap(8 * GIB, true, Some((7 * GIB, GIB))),
            heap(32 * GIB, false, Some((20 * GIB, 3 * GIB))),
        ];
        let b = heap_budgets(&with_ext, None);
        assert_eq!(b[0].bytes, 6 * GIB);
        assert_eq!(b[1].bytes, 17 * GIB);
        assert_eq!(
            b[0].source,
            BudgetSource::MemoryBudgetExt(ReportedBudget {
                budget: 7 * GIB,
                usage: GIB
            })
        );
        // Usage above the budget leaves nothing, not a wrapped figure
        let b = heap_budgets(&[heap(8 * GIB, true, Some((GIB, 2 * GIB)))], None);
        assert_eq!(b[0].bytes, 0);
        // A zero heapBudget is a driver that did not fill it in: heap size
        let b = heap_budgets(&[heap(10 * GIB, true, Some((0, 0)))], None);
        assert_eq!(b[0].bytes, 8 * GIB);
        // The variable replaces every heap's budget
        let b = heap_budgets(&with_ext, Some(4_000_000));
        assert!(b
            .iter()
            .all(|h| h.bytes == 4_000_000 && h.source == BudgetSource::Environment));
    }

    /// The variable must be a whole number of bytes above 0; the messages
    /// name it and say what to give.
    #[test]
    fn invalid_budget_variable_is_refused() {
        assert_eq!(budget_from_env(None).unwrap(), None);
        assert_eq!(budget_from_env(Some(" 4000000 ")).unwrap(), Some(4_000_000));
        for bad in ["lots", "", "-5", "1.5e9", "0"] {
            let e = budget_from_env(Some(bad)).unwrap_err().to_string();
            assert!(e.starts_with(&format!("{BUDGET_ENV}=")), "{e}");
            assert!(e.contains("unset it to use the device's budget"), "{e}");
        }
        let e = budget_from_env(Some("0")).unwrap_err().to_string();
        assert!(e.contains("leaves no device memory"), "{e}");
    }

    /// Each kind of buffer is charged to the heap gpu-allocator takes its
    /// memory from: on a discrete GPU device buffers to VRAM and staging to
    /// host memory (or to VRAM where a host-visible device-local type comes
    /// first); on a unified-memory device such as lavapipe, all to heap 0.
    #[test]
    fn buffers_are_charged_to_the_heap_their_memory_comes_from() {
        use vk::MemoryPropertyFlags as F;
        let t = |flags, heap| MemoryType { flags, heap };
        let discrete = [
            t(F::DEVICE_LOCAL, 0),
            t(F::HOST_VISIBLE | F::HOST_COHERENT, 1),
            t(F::HOST_VISIBLE | F::HOST_COHERENT | F::HOST_CACHED, 1),
        ];
        let heap_of = |types: &[MemoryType], bits, loc| {
            memory_type_for(types, bits, loc).map(|i| types[i].heap)
        };
        assert_eq!(heap_of(&discrete, 0b111, MemoryLocation::GpuOnly), Some(0));
        assert_eq!(heap_of(&discrete, 0b111, MemoryLocation::CpuToGpu), Some(1));
        assert_eq!(heap_of(&discrete, 0b111, MemoryLocation::GpuToCpu), Some(1));
        // Types the buffer does not accept are skipped
        assert_eq!(
            memory_type_for(&discrete, 0b100, MemoryLocation::CpuToGpu),
            Some(2)
        );
        assert_eq!(
            memory_type_for(&discrete, 0b010, MemoryLocation::GpuOnly),
            None
        );
        // Resizable BAR: a host-visible device-local type is preferred for uploads
        let rebar = [
            t(F::DEVICE_LOCAL, 0),
            t(F::HOST_VISIBLE | F::HOST_COHERENT, 1),
            t(F::DEVICE_LOCAL | F::HOST_VISIBLE | F::HOST_COHERENT, 0),
        ];
        assert_eq!(heap_of(&rebar, 0b111, MemoryLocation::CpuToGpu), Some(0));
        // lavapipe: one type, one heap
        let uma = [t(
            F::DEVICE_LOCAL | F::HOST_VISIBLE | F::HOST_COHERENT | F::HOST_CACHED,
            0,
        )];
        for loc in [
            MemoryLocation::GpuOnly,
            MemoryLocation::CpuToGpu,
            MemoryLocation::GpuToCpu,
        ] {
            assert_eq!(heap_of(&uma, 0b1, loc), Some(0));
        }
    }
}
