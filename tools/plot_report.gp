# Plots of ice-report (run by it): gnuplot -e "dir='OUT'; methods='ice ice_area qem_ext qem_idt'" plot_report.gp
# Reads OUT/plot_*.dat (written by ice-report) and writes OUT/{errors,errors_median,phases,speedup}.svg.
if (!exists("dir")) dir = "."
if (!exists("methods")) methods = "ice ice_area qem_ext qem_idt"
problems = "poisson heat geodesic"
titles = "'Poisson (rel. L2)' 'long-time heat (rel. L2)' 'geodesic (mean / max distance)'"
nm = words(methods)
set terminal svg size 1500,480 dynamic font "Helvetica,13"
set key top right
set grid

# Error vs coarse size, every mesh and budget, one colour per method.
set output dir."/errors.svg"
set multiplot layout 1,3 title "Error of the prolonged coarse solution vs coarse vertex count"
set logscale xy
set xlabel "coarse vertices"
set ylabel "error"
set format y "%g"
do for [p=1:3] {
  set title word(titles, p)
  plot for [m=0:nm-1] dir."/plot_error_".word(problems, p).".dat" index m using 1:2 with points pt 7 ps 0.6 title word(methods, m+1)
}
unset multiplot

# Median error vs budget.
set output dir."/errors_median.svg"
set multiplot layout 1,3 title "Median error over the meshes vs coarse budget"
set xlabel "budget (% of the input vertices)"
do for [p=1:3] {
  set title word(titles, p)
  plot for [m=0:nm-1] dir."/plot_median_".word(problems, p).".dat" index m using 1:2 with linespoints lw 2 pt 7 title word(methods, m+1)
}
unset multiplot
unset logscale

# Mean time per phase (over meshes and budgets; summed over the three problems), per method and fine.
set output dir."/phases.svg"
set terminal svg size 900,500 dynamic font "Helvetica,13"
set title "Mean time per phase (s), all three problems, per mesh and budget"
set style data histograms
set style histogram rowstacked
set style fill solid 0.8 border -1
set boxwidth 0.6
set xlabel ""
set ylabel "seconds"
set logscale y
set yrange [1e-4:*]
unset logscale y
set yrange [0:*]
set key outside right
plot dir."/plot_phases.dat" using 2:xtic(1) title "coarsen", '' using 3 title "assemble", '' using 4 title "factor", \
     '' using 5 title "solve", '' using 6 title "prolong"

# Speed-up vs fine.
set output dir."/speedup.svg"
set terminal svg size 1000,480 dynamic font "Helvetica,13"
set style data linespoints
set key top right
unset style
set title "Speed-up vs the fine solve (median over meshes, first method)"
set xlabel "budget (% of the input vertices)"
set ylabel "speed-up (x)"
set logscale y
set yrange [*:*]
plot for [p=0:2] dir."/plot_speedup.dat" index p using 1:3 with linespoints lw 2 pt 7 title word(problems, p+1)." per solve", \
     for [p=0:2] dir."/plot_speedup.dat" index p using 1:2 with linespoints lw 2 dt 2 pt 5 title word(problems, p+1)." end to end"
