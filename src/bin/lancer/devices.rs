//! `lancer devices`: the Vulkan devices lancer can use, one line each.

use anyhow::Result;

use lancer::internal::vk;

/// `lancer devices`.
pub fn devices() -> Result<()> {
    let list = vk::list_devices()?;
    for d in &list {
        println!(
            "{}: {} ({:?}, Vulkan {}.{}.{}, driver {}, maxStorageBufferRange {} MiB, subgroup {})",
            d.index,
            d.name,
            d.kind,
            d.api_version.0,
            d.api_version.1,
            d.api_version.2,
            d.driver_name,
            d.max_storage_buffer_range >> 20,
            d.subgroup_size
        );
    }
    Ok(())
}
